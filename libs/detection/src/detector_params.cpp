// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/detector_params.hpp"

#include <fmt/format.h>

namespace v4r::detection {

ViewRange resolve_view_range(const ViewRange& v, double radius, double focal_px) {
  ViewRange out = v;
  if (out.distance_min_m <= 0.0) out.distance_min_m = focal_px * 2.0 * radius / 400.0;
  if (out.distance_max_m <= 0.0) out.distance_max_m = focal_px * 2.0 * radius / 150.0;
  if (out.distance_max_m < out.distance_min_m) out.distance_max_m = out.distance_min_m;
  return out;
}

void add_params(ParamRegistry& r, DetectorParams& p) {
  auto& v = p.views;
  r.add("detect.views.elevation_min", &v.elevation_min_deg, -89.0, 89.0, "deg", "lowest camera elevation above the object's x-y plane");
  r.add("detect.views.elevation_max", &v.elevation_max_deg, -89.0, 89.0, "deg", "highest camera elevation");
  r.add("detect.views.azimuth_min", &v.azimuth_min_deg, -360.0, 360.0, "deg", "first camera azimuth about the object's z axis");
  r.add("detect.views.azimuth_max", &v.azimuth_max_deg, -360.0, 720.0, "deg", "last camera azimuth (a span of 360: all around)");
  r.add("detect.views.inplane_min", &v.inplane_min_deg, -180.0, 180.0, "deg", "smallest turn of the image about the optical axis");
  r.add("detect.views.inplane_max", &v.inplane_max_deg, -180.0, 180.0, "deg", "largest turn of the image about the optical axis");
  r.add("detect.views.distance_min", &v.distance_min_m, 0.0, 100.0, "m", "nearest camera distance to the object's centre (0: where the object spans 400 px)");
  r.add("detect.views.distance_max", &v.distance_max_m, 0.0, 100.0, "m", "farthest camera distance to the object's centre (0: where it spans 150 px)");
  auto& t = p.templates;
  r.add("detect.templates.view_step", &t.view_step_deg, 2.0, 45.0, "deg", "elevation and azimuth step between template views");
  r.add("detect.templates.inplane_step", &t.inplane_step_deg, 2.0, 90.0, "deg", "step between in-plane rotations");
  r.add("detect.templates.scale_step", &t.scale_step, 1.02, 2.0, "", "distance ratio between template scales");
  r.add("detect.templates.coarse_stride", &t.coarse_stride, 1, 4, "", "every n-th view along each grid axis has a coarse template (its children: the views within n/2 steps)");
  r.add("detect.templates.coarse_features", &t.coarse_features, 4, 63, "", "orientation features per coarse template (1/4 resolution)");
  r.add("detect.templates.fine_features", &t.fine_features, 8, 63, "", "orientation features per fine template (1/2 resolution)");
  r.add("detect.templates.crease_angle", &t.crease_angle_deg, 0.0, 90.0, "deg", "edges between faces closer than this in normal are not in templates");
  auto& s = p.search;
  r.add("detect.search.min_gradient", &s.min_gradient, 0.0, 255.0, "grey/px",
        "highest orientation threshold: weaker gradients carry no orientation (noisy frames)");
  r.add("detect.search.min_gradient_floor", &s.min_gradient_floor, 0.0, 255.0, "grey/px",
        "lowest orientation threshold (clean frames, blurred edges)");
  r.add("detect.search.noise_factor", &s.noise_factor, 0.0, 20.0, "",
        "orientation threshold = this x the level's median |gx|+|gy|, within min_gradient_floor .. min_gradient (0: min_gradient)");
  r.add("detect.search.coarse_spread", &s.coarse_spread, 0, 8, "px", "orientation spreading radius at 1/4 resolution");
  r.add("detect.search.fine_spread", &s.fine_spread, 0, 8, "px", "orientation spreading radius at 1/2 resolution");
  r.add("detect.search.coarse_min_score", &s.coarse_min_score, 0.0, 1.0, "", "share of the best coarse score a candidate needs");
  r.add("detect.search.coarse_candidates", &s.coarse_candidates, 1, 1024, "", "coarse candidates probed at 1/2 resolution with their own view");
  r.add("detect.search.fine_expand", &s.fine_expand, 1, 1024, "", "best probed candidates whose neighbouring views are searched at 1/2 resolution");
  r.add("detect.search.fine_window", &s.fine_window, 0, 8, "px", "half window at 1/2 resolution around a coarse candidate");
  r.add("detect.search.max_hypotheses", &s.max_hypotheses, 1, 64, "", "hypotheses refined and verified per frame");
  r.add("detect.search.extra_hypotheses", &s.extra_hypotheses, 0, 64, "",
        "when none of those is verified, this many more are refined and verified (0: none)");
  auto& f = p.verify;
  r.add("detect.verify.sample_spacing", &f.sample_spacing_px, 1.0, 50.0, "px", "spacing of the projected model's edge samples");
  r.add("detect.verify.max_samples", &f.max_samples, 16, 4096, "", "edge samples per pose at most");
  r.add("detect.verify.refine_samples", &f.refine_samples, 16, 4096, "",
        "edge samples per pose at most in the refinement (depth scan and iterations)");
  r.add("detect.verify.refine_search", &f.refine_search_px, 1.0, 64.0, "px", "search range along the normal of the first refinement pass");
  r.add("detect.verify.depth_scan_steps", &f.depth_scan_steps, 0, 20, "", "distances tried either side of a hypothesis before its refinement");
  r.add("detect.verify.depth_scan_step", &f.depth_scan_step, 0.001, 0.5, "", "relative distance step of that scan");
  r.add("detect.verify.refine_iterations", &f.refine_iterations, 0, 100, "", "iterations of the 6-DoF edge alignment of a hypothesis");
  r.add("detect.verify.polish_iterations", &f.polish_iterations, 0, 100, "",
        "iterations polishing the best verified pose over all its edge samples, edges placed to a fraction of a pixel (0: off)");
  r.add("detect.verify.polish_range", &f.polish_range_px, 0.5, 32.0, "px",
        "search range and Tukey width of that polish along the edge normal");
  r.add("detect.verify.plateau", &f.plateau_px, 0.0, 32.0, "px",
        "a gradient plateau this wide along the normal (a blurred edge) is matched at its centroid in the alignment and polish (0: off)");
  r.add("detect.verify.unfold_faces", &f.unfold_faces, 0, 8, "",
        "large faces of the best verified pose seen edge-on that are turned into view, polished and kept when the edge score rises (0: off)");
  r.add("detect.verify.unfold_deg", &f.unfold_deg, 0.5, 45.0, "deg", "... faces seen at less than this are turned to be seen at this");
  r.add("detect.verify.unfold_band", &f.unfold_band_deg, 0.0, 45.0, "deg", "... as are faces turned away by at most this");
  r.add("detect.verify.unfold_gain", &f.unfold_gain, 0.0, 1.0, "", "... an unfolded pose is kept when its edge score rises by at least this");
  r.add("detect.verify.refine_tukey", &f.refine_tukey_px, 0.0, 64.0, "px",
        "after the first third of the alignment, matches are weighted by Tukey's biweight of this width (0: Huber throughout)");
  r.add("detect.verify.match_distance", &f.match_distance_px, 0.5, 10.0, "px", "a sample matches a gradient this close along its normal");
  r.add("detect.verify.match_angle", &f.match_angle_deg, 1.0, 90.0, "deg", "largest angle between a matching gradient and the edge normal");
  r.add("detect.verify.min_gradient", &f.min_gradient, 0.0, 255.0, "grey/px",
        "highest threshold of a gradient that matches a sample (noisy frames)");
  r.add("detect.verify.min_gradient_floor", &f.min_gradient_floor, 0.0, 255.0, "grey/px",
        "lowest threshold of a matching gradient (clean frames, blurred edges)");
  r.add("detect.verify.noise_factor", &f.noise_factor, 0.0, 20.0, "",
        "matching threshold = this x the frame's median |gx|+|gy|, within min_gradient_floor .. min_gradient (0: min_gradient)");
  r.add("detect.verify.min_samples", &f.min_samples, 3, 4096, "", "fewer visible edge samples: the pose is not verified");
  r.add("detect.verify.peak_tolerance", &f.peak_tolerance, 1.0, 10.0, "",
        "a matching gradient is an edge: its neighbours 1 px along the normal have at most this times its gradient");
  r.add("detect.verify.tangent_support", &f.tangent_support, 0, 4, "px",
        "a sample's gradient is summed over this many pixels either side along the edge (noise averages out; 0: one pixel)");
  r.add("detect.verify.short_pieces", &f.short_pieces, "an edge piece shorter than min_run samples counts when all of it matches");
  r.add("detect.verify.min_run", &f.min_run, 1, 64, "", "matched samples count only in runs of this many consecutive matches along an edge");
  r.add("detect.verify.run_gap", &f.run_gap, 0, 8, "",
        "a run of matches goes on over up to this many unmatched samples in a row when a match of its polarity follows (0: off)");
  r.add("detect.verify.continued_reach", &f.continued_reach, 0.0, 4.0, "",
        "an edge whose line the image continues past both ends does not count: probed out to this x its length (12..40 px; 0: off)");
  r.add("detect.verify.continued_share", &f.continued_share, 0.1, 1.0, "",
        "... an end is continued when this share of its probes (every 4 px) match a gradient of the edge's orientation");
  r.add("detect.verify.accept_score", &f.accept_score, 0.0, 1.0, "", "share of matched edge samples of a verified pose");
  r.add("detect.verify.leak_score", &f.leak_score, 0.0, 1.0, "",
        "a pose scoring this or more (below accept_score) is verified when its silhouette stands out in colour (colour images; >= accept_score: off)");
  r.add("detect.verify.max_leak", &f.max_leak, 0.0, 1.0, "",
        "... when at most this share of the colours just outside its silhouette look like those just inside");
  r.add("detect.verify.leak_min_samples", &f.leak_min_samples, 1, 4096, "", "... and at least this many colour samples lie outside it");
  r.add("detect.verify.leak_group_samples", &f.leak_group_samples, 0, 4096, "",
        "an outside colour is compared with the inside colours of its own silhouette edge when that edge has this many samples (0: with all)");
  r.add("detect.verify.colour_ambiguity", &f.colour_ambiguity, 0.0, 1.0, "",
        "a pose verified by colour is withdrawn when a distinct verified pose, not its near-symmetric twin, scores at least its score minus this (0: off)");
  r.add("detect.verify.twins_ambiguous", &f.twins_ambiguous,
        "a near-symmetric twin within the ambiguity margins withdraws a pose too (false: the twin test judges the pair)");
  r.add("detect.verify.edge_ambiguity", &f.edge_ambiguity, 0.0, 1.0, "",
        "a pose verified by its edges is withdrawn when a distinct verified pose scores at least its score minus this (0: off)");
  r.add("detect.verify.distinct_m", &f.distinct_m, 0.0, 10.0, "m", "poses farther apart than this are distinct (colour ambiguity)");
  r.add("detect.verify.distinct_deg", &f.distinct_deg, 0.0, 180.0, "deg", "... or turned further apart than this");
  r.add("detect.verify.stand_out_score", &f.stand_out_score, 0.0, 1.0, "",
        "with nothing verified otherwise, the best pose is verified when it scores at least this (>= accept_score: off),");
  r.add("detect.verify.stand_out_margin", &f.stand_out_margin, 0.0, 1.0, "", "... every distinct pose scores at least this less");
  r.add("detect.verify.stand_out_max_leak", &f.stand_out_max_leak, 0.0, 1.0, "", "... and its silhouette leaks at most this (colour images)");
  r.add("detect.verify.stand_out_leak_margin", &f.stand_out_leak_margin, 0.0, 1.0, "",
        "... a distinct pose within stand_out_margin is no rival when its silhouette leaks this much more, and at least stand_out_max_leak (1: off)");
  r.add("detect.verify.near_symmetry", &f.near_symmetry, 0.0, 0.5, "",
        "near symmetries within this share of the model's diagonal give a pose twins it must beat (twin_margin; 0: none)");
  r.add("detect.verify.twin_margin", &f.twin_margin, 0.0, 1.0, "",
        "a pose and its near-symmetric twin: the one whose distinctive edge samples match by this share more is kept (0: off)");
  r.add("detect.verify.twin_residual_margin", &f.twin_residual_margin, 0.0, 4.0, "px",
        "... neither ahead by that share: the one whose distinctive samples lie nearer the centres of the image's edges by this mean distance "
        "(blurred images; 0: off)");
  r.add("detect.verify.tie_score", &f.tie_score, 0.0, 1.0, "",
        "distinct verified poses scoring within this of the best are compared with it where their edge samples differ (0: off)");
  r.add("detect.verify.tie_margin", &f.tie_margin, 0.0, 1.0, "",
        "... and ranked first when their distinctive edge samples match by this share more");
  r.add("detect.verify.enclosing_factor", &f.enclosing_factor, 0.0, 10.0, "",
        "a verified pose nested in the box of a distinct one that stands out and matches this many times as many edge samples gives way to it (0: off)");
  r.add("detect.verify.consensus_score", &f.consensus_score, 0.0, 1.0, "",
        "verified poses near the best one (consensus_deg, consensus_m) scoring within this of it: with 3 or more, their medoid is ranked first (0: off)");
  r.add("detect.verify.consensus_deg", &f.consensus_deg, 0.1, 180.0, "deg", "... turned at most this from the best one");
  r.add("detect.verify.consensus_m", &f.consensus_m, 0.001, 10.0, "m", "... and at most this far from it");
  r.add("detect.verify.view_margin", &f.view_margin_deg, 0.0, 180.0, "deg",
        "a hypothesis refined outside the view range (detect.views.*) widened by this in elevation and distance is dropped (180: never)");
  r.add("detect.verify.inplane_margin", &f.inplane_margin_deg, 0.0, 180.0, "deg",
        "... and one refined beyond the in-plane turns widened by this");
  auto& c = p.colour;
  r.add("detect.colour.enabled", &c.enabled,
        "models with a face colour: search only around regions of that colour at 1/4 resolution (colour images)");
  r.add("detect.colour.max_distance", &c.max_distance, 0.005, 0.5, "",
        "chromaticity distance (normalised r = R/(R+G+B), g = G/(R+G+B)) of a pixel of the model's colour");
  r.add("detect.colour.min_brightness", &c.min_brightness, 0.0, 255.0, "grey", "darker pixels (mean of R, G, B) carry no chromaticity");
  r.add("detect.colour.min_area_ratio", &c.min_area_ratio, 0.01, 1.0, "", "smallest region area over a template's coloured area (occlusion)");
  r.add("detect.colour.max_area_ratio", &c.max_area_ratio, 1.0, 10.0, "", "largest region area over a template's coloured area");
  r.add("detect.colour.min_region", &c.min_region_px, 1, 10000, "px^2", "smallest region at 1/4 resolution");
  r.add("detect.colour.margin", &c.margin, 0, 32, "px", "at 1/4 resolution: how far a template's coloured footprint may miss a region");
  r.add("detect.colour.max_regions", &c.max_regions, 1, 64, "", "largest plausible colour regions searched per frame");
  r.add("detect.colour.roi_margin", &c.roi_margin, 0, 1000, "px",
        "gradients only in the box of the templates placed over the colour regions, grown by this");
  r.add("detect.colour.coarse_candidates", &c.coarse_candidates, 1, 1024, "",
        "coarse candidates probed at 1/2 resolution when the colour regions fix place and size");
  r.add("detect.colour.fine_expand", &c.fine_expand, 1, 1024, "", "best probed candidates expanded, with colour regions");
  r.add("detect.colour.max_hypotheses", &c.max_hypotheses, 1, 64, "",
        "hypotheses refined and verified per frame with colour regions (at most detect.search.max_hypotheses)");
}

Expected<void> validate(const DetectorParams& p) {
  const auto bad = [](const char* field, std::string msg) {
    Error e;
    e.field = field;
    e.message = std::move(msg);
    return Unexpected{std::move(e)};
  };
  const ViewRange& v = p.views;
  if (v.elevation_min_deg > v.elevation_max_deg)
    return bad("detect.views.elevation_min", fmt::format("{} is above elevation_max {}", v.elevation_min_deg, v.elevation_max_deg));
  if (v.elevation_min_deg < -89.0 || v.elevation_max_deg > 89.0)
    return bad("detect.views.elevation_max", "elevations must lie within -89 .. 89 degrees");
  if (v.azimuth_min_deg > v.azimuth_max_deg)
    return bad("detect.views.azimuth_min", fmt::format("{} is above azimuth_max {}", v.azimuth_min_deg, v.azimuth_max_deg));
  if (v.inplane_min_deg > v.inplane_max_deg)
    return bad("detect.views.inplane_min", fmt::format("{} is above inplane_max {}", v.inplane_min_deg, v.inplane_max_deg));
  if (v.distance_min_m < 0.0 || v.distance_max_m < 0.0)
    return bad("detect.views.distance_min", "distances must be positive (or 0: automatic)");
  if (v.distance_min_m > 0.0 && v.distance_max_m > 0.0 && v.distance_min_m > v.distance_max_m)
    return bad("detect.views.distance_min", fmt::format("{} is above distance_max {}", v.distance_min_m, v.distance_max_m));
  if (!(p.templates.scale_step > 1.0)) return bad("detect.templates.scale_step", "must be above 1");
  if (!(p.templates.view_step_deg > 0.0)) return bad("detect.templates.view_step", "must be positive");
  if (!(p.templates.inplane_step_deg > 0.0)) return bad("detect.templates.inplane_step", "must be positive");
  if (p.templates.coarse_features < 4 || p.templates.coarse_features > 63)
    return bad("detect.templates.coarse_features", "must lie within 4 .. 63");
  if (p.templates.fine_features < 8 || p.templates.fine_features > 63)
    return bad("detect.templates.fine_features", "must lie within 8 .. 63");
  if (p.templates.coarse_stride < 1 || p.templates.coarse_stride > 4)
    return bad("detect.templates.coarse_stride", "must lie within 1 .. 4");
  if (p.search.max_hypotheses < 1) return bad("detect.search.max_hypotheses", "must be at least 1");
  if (p.colour.min_area_ratio > p.colour.max_area_ratio)
    return bad("detect.colour.min_area_ratio", fmt::format("{} is above max_area_ratio {}", p.colour.min_area_ratio, p.colour.max_area_ratio));
  if (p.colour.max_regions < 1) return bad("detect.colour.max_regions", "must be at least 1");
  return {};
}

}  // namespace v4r::detection
