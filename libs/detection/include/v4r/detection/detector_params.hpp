// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include "v4r/core/params.hpp"

namespace v4r::detection {

/// \brief The range of views the detector searches: where the camera may be around the object
/// (elevation above the object's x-y plane, azimuth about its z axis, distance from the centre
/// of its bounding box) and how far the image may be turned about the optical axis.
struct ViewRange {
  double elevation_min_deg = 15.0;  ///< degrees, -89 .. 89
  double elevation_max_deg = 75.0;  ///< degrees
  double azimuth_min_deg = 0.0;     ///< degrees; a span of 360 or more is the full circle
  double azimuth_max_deg = 360.0;   ///< degrees
  double inplane_min_deg = -30.0;   ///< degrees: turn of the image about the optical axis
  double inplane_max_deg = 30.0;    ///< degrees
  /// Metres, camera to the bounding box centre; 0: where the model's bounding sphere spans
  /// 400 px across (see resolve_view_range).
  double distance_min_m = 0.0;
  double distance_max_m = 0.0;      ///< metres; 0: where the bounding sphere spans 150 px
};

/// \brief How the view templates are sampled (offline; part of the template cache key).
struct TemplateParams {
  double view_step_deg = 7.0;      ///< degrees between neighbouring views in elevation and azimuth
  double inplane_step_deg = 7.0;   ///< degrees between in-plane rotations
  double scale_step = 1.12;        ///< ratio of neighbouring template distances (> 1)
  int coarse_stride = 2;           ///< every coarse_stride-th view along each grid axis gets a coarse template
  int coarse_features = 32;        ///< features per coarse template (1/4 resolution)
  int fine_features = 48;          ///< features per fine template (1/2 resolution)
  double crease_angle_deg = 10.0;  ///< edges between faces closer than this in normal are no edge
};

/// \brief The online search: gradients, spreading, coarse-to-fine template matching.
struct SearchParams {
  /// Grey levels per pixel (a step of 2x this across an edge): weaker gradients carry no
  /// orientation. The highest threshold: a frame's threshold is relative to its noise, see
  /// GradientThreshold (each level's noise: median of |gx| + |gy| at that level).
  double min_gradient = 8.0;
  double min_gradient_floor = 3.0;  ///< grey/px: the lowest threshold (with noise_factor > 0)
  /// threshold = noise_factor x the level's noise, within floor .. min_gradient; 0: min_gradient
  /// (the default: measured, weak orientations of textured backgrounds cost the thin-plate
  /// models more at the search than blurred edges gain; the verification's is relative).
  double noise_factor = 0.0;
  int coarse_spread = 2;          ///< px at 1/4 resolution: orientations spread over (2r+1)^2
  int fine_spread = 2;            ///< px at 1/2 resolution
  double coarse_min_score = 0.5;  ///< share of the best possible coarse score a candidate needs
  int coarse_candidates = 300;    ///< coarse candidates probed at the fine level (their own view)
  int fine_expand = 256;          ///< best probed candidates whose neighbouring views are searched
  int fine_window = 2;            ///< px at 1/2 resolution searched around a coarse candidate
  int max_hypotheses = 16;        ///< hypotheses refined and verified per frame
  /// When none of those is verified, this many more (the next best distinct candidates) are
  /// refined and verified: a partly hidden object whose view ranks lower (0: none). 24 rather
  /// than 8: the occluded or blurred section's right candidate often ranks beyond the 24th (through
  /// the search, 378 -> 391 of 480 renders found); each costs an image without a verified pose
  /// about 1.4 ms.
  int extra_hypotheses = 24;
};

/// \brief Local refinement and verification of a hypothesis against the image's edges.
struct VerifyParams {
  double sample_spacing_px = 5.0;   ///< px between edge samples of the projected model
  int max_samples = 400;            ///< at most this many samples (spacing grows on large views)
  /// At most this many samples in the refinement's depth scan and iterations (verification uses
  /// max_samples): six degrees of freedom need far fewer than the verdict does.
  int refine_samples = 120;
  double refine_search_px = 12.0;   ///< px searched along the normal in the first refinement pass
  int depth_scan_steps = 3;         ///< distances tried either side of a hypothesis before refining
  double depth_scan_step = 0.03;    ///< relative distance step of that scan
  int refine_iterations = 12;       ///< Gauss-Newton iterations of the 6-DoF edge alignment
  /// After the first third of those iterations, samples are weighted by Tukey's biweight with
  /// this width (px): a match farther off (an occluder's edge, a texture line) stops pulling the
  /// pose. 0: Huber (1.5 px) throughout.
  double refine_tukey_px = 4.5;
  /// The best verified pose is polished: this many Gauss-Newton iterations over all its edge
  /// samples (up to max_samples) with the edge placed to a fraction of a pixel, matches within
  /// polish_range px weighted by Tukey's biweight of that width (0: off).
  int polish_iterations = 10;
  double polish_range_px = 1.5;
  /// A gradient plateau along the normal at least this wide (px: a motion-blurred edge, each
  /// pixel at least half the plateau's peak, same polarity) is matched at its centroid in the
  /// alignment and the polish, not at its strongest or nearest pixel (0: off).
  double plateau_px = 4.0;
  /// After its polish, the best verified pose tries to unfold its faces seen edge-on
  /// (GrazingFaces): each face of at least a tenth of the largest face's area, turned away by at
  /// most unfold_band_deg or seen at less than unfold_deg, is turned to be seen at unfold_deg
  /// (about the centroid of the pose's edge samples); the turned pose is polished and kept when
  /// its edge score rises by unfold_gain. At most unfold_faces faces, the largest first (0: off).
  int unfold_faces = 2;
  double unfold_deg = 6.0;
  double unfold_band_deg = 15.0;
  double unfold_gain = 0.01;
  double match_distance_px = 1.5;   ///< px: a sample matches a gradient this close along its normal
  double match_angle_deg = 15.0;    ///< degrees: ... whose orientation is this close to the edge normal
  /// Grey levels per pixel of a matching gradient (a step of 2x this): the highest threshold, as
  /// detect.search.min_gradient, relative to the full-resolution noise of the frame.
  double min_gradient = 8.0;
  double min_gradient_floor = 3.0;  ///< grey/px: the lowest threshold (clean images; blur)
  double noise_factor = 1.5;        ///< threshold = noise_factor x the frame's noise, within floor .. min_gradient (0: min_gradient)
  int min_samples = 30;             ///< fewer visible samples: a pose cannot be verified
  double peak_tolerance = 1.0;      ///< a match's neighbours along the normal may have at most this times its gradient
  /// px either side along the edge over which a sample's gradient is summed (0: the pixel alone):
  /// noise averages out without blurring across the edge.
  int tangent_support = 1;
  bool short_pieces = true;         ///< an edge piece shorter than min_run counts when all of it matches
  int min_run = 4;                  ///< consecutive matched samples of one polarity along an edge that count
  /// A run goes on over up to this many unmatched samples in a row (a blurred or noisy spot, an
  /// occluder's boundary) when a match of its polarity follows them; they do not count. 0: off.
  int run_gap = 1;
  /// An edge piece whose line the image continues beyond both its ends (an occluder's side, a
  /// line of the background that a wrong pose lies along) does not count: probes every 4 px out
  /// to this times the piece's length (12..40 px) past each end, none on the pose's own edges,
  /// each matched by a gradient of the edge's orientation within match_distance_px; 0: off.
  double continued_reach = 0.5;
  double continued_share = 0.8;     ///< ... an end is continued when this share of its probes match a gradient
  double accept_score = 0.75;       ///< share of samples matched for a verified pose
  /// A pose scoring at least this (below accept_score) is verified when its silhouette stands
  /// out in colour (EdgeAligner::measure_leak: leak <= max_leak): an occluded, noisy or blurred
  /// object. Colour images only; >= accept_score: off.
  double leak_score = 0.5;
  double max_leak = 0.25;           ///< largest leak of such a pose
  int leak_min_samples = 30;        ///< fewer colour samples outside its silhouette: not verified this way
  /// An outside colour is compared with the inside colours of its own silhouette edge when that
  /// edge has at least this many samples (a face in shadow beside a lit one; 0: with all of them).
  int leak_group_samples = 12;
  /// Such a pose is withdrawn when another verified pose, distinct (distinct_m, distinct_deg,
  /// beyond the model's symmetries), scores at least its score minus this (0: off); not for its
  /// near-symmetric twin when twin_margin > 0 (the twin test judges the pair) unless
  /// twins_ambiguous.
  double colour_ambiguity = 0.05;
  bool twins_ambiguous = false;     ///< a near-symmetric twin withdraws a pose too (see above)
  double edge_ambiguity = 0.0;      ///< the same for a pose verified by its edges (0: off)
  double distinct_m = 0.05;         ///< metres: poses farther apart are distinct
  double distinct_deg = 5.0;        ///< degrees: ... or turned further apart
  /// When no pose is verified otherwise, the best-scoring one is verified when it stands out: it
  /// scores at least stand_out_score, every distinct pose (distinct_m, distinct_deg, beyond the
  /// symmetries) scores at least stand_out_margin less, and its silhouette leaks at most
  /// stand_out_max_leak (colour images only). A partly hidden object: its visible edges match,
  /// nothing else in the image comes close. stand_out_score >= accept_score: off.
  double stand_out_score = 0.55;
  double stand_out_margin = 0.08;
  double stand_out_max_leak = 0.5;
  /// ... where a distinct pose within stand_out_margin (or scoring more) is no rival when its
  /// silhouette leaks at least this much more, and at least stand_out_max_leak (an outline on
  /// clutter or on the object's print); then every pose scoring stand_out_score may stand out,
  /// the best-scoring first (1: off).
  double stand_out_leak_margin = 0.2;
  /// Near symmetries (detection::near_symmetries) within this share of the model's bounding-box
  /// diagonal: each gives a pose a twin, compared with it by twin_margin (0: none).
  double near_symmetry = 0.05;
  /// The best verified and the best-scoring pose are each compared with their twin under every
  /// near symmetry on the edge samples where they differ (EdgeAligner::compare_twins, farther than 2 x match_distance_px
  /// apart): the twin replaces the pose when the share of its distinctive samples that match
  /// exceeds the pose's by this; a pose stands out from its twin (stand_out_*) when its share
  /// exceeds the twin's by this, or, with too few such samples or neither ahead, when the twin
  /// scores stand_out_margin less (0: the twins are not compared, only scored).
  double twin_margin = 0.15;
  /// Neither ahead by twin_margin (a blurred image: both poses' distinctive samples lie on the
  /// smeared edges): the pose whose distinctive samples lie nearer the centres of the image's
  /// edges, by at least this mean distance (px), is ahead (EdgeAligner::TwinShares::residual_*;
  /// 0: off).
  double twin_residual_margin = 0.25;
  /// Near ties: when distinct verified poses (beyond distinct_m / distinct_deg, modulo the
  /// symmetries) score within tie_score of the best one, the first of them whose distinctive edge
  /// samples (as for twins) match by tie_margin more than the best one's is ranked first (0: off).
  double tie_score = 0.05;
  double tie_margin = 0.05;
  /// A verified pose nested in another: when the best verified pose's edge samples lie within the
  /// box of a distinct pose (covering at most 0.8 of it) that scores at least stand_out_score,
  /// whose silhouette leaks at most stand_out_max_leak and no more than its own, and which
  /// matches at least enclosing_factor times as many edge samples in runs, the enclosing pose is
  /// verified and ranked first, the nested one no longer verified (0: off).
  double enclosing_factor = 1.0;
  /// Consensus: the verified poses within consensus_deg and consensus_m (modulo the symmetries)
  /// of the best one and scoring within consensus_score of it form its cluster; with three or more
  /// members its medoid (the member nearest to all others) is ranked first. Edges blurred or few
  /// hold a refined pose some degrees off the truth as well as at it; refinements from different
  /// templates scatter around the truth (0: off).
  double consensus_score = 0.05;
  double consensus_deg = 8.0;
  double consensus_m = 0.05;
  /// Degrees: a hypothesis refined to a pose outside the view range (detect.views.*, every
  /// symmetric equivalent) widened by this in elevation and distance (in_view_range), and by
  /// inplane_margin_deg in the image's turn, is dropped (180: never): a far pose seen edge-on,
  /// below the elevations searched, fits the outline of one face of the object.
  double view_margin_deg = 5.0;
  double inplane_margin_deg = 15.0;
};

/// \brief The colour stage (the paper's sponge): used when the model's faces carry a colour
/// (.cao `colour=R,G,B`, or `--colour`) and the image is in colour.
struct ColourParams {
  bool enabled = true;          ///< search only around regions of the model's colour
  double max_distance = 0.06;   ///< chromaticity (normalised r, g) distance of a matching pixel
  double min_brightness = 25.0; ///< grey levels: darker 4x4 blocks (mean of R, G, B) carry no chromaticity
  double min_area_ratio = 0.4;  ///< a region's area over a template's coloured area, at least (occlusion)
  double max_area_ratio = 1.6;  ///< ... at most (blur, shadows of the same colour)
  int min_region_px = 4;        ///< px at 1/4 resolution: smaller regions are noise
  int margin = 3;               ///< px at 1/4 resolution: a template's coloured footprint may miss a region by this
  int max_regions = 8;          ///< largest plausible regions searched per frame
  /// px (full resolution): gradients are computed only in the box of the templates placed over the
  /// regions (each grown by 15 %, for the fine level's neighbours), grown by this (refinement)
  int roi_margin = 32;
  int coarse_candidates = 100;  ///< as detect.search.coarse_candidates, when the colour regions are searched
  int fine_expand = 24;         ///< as detect.search.fine_expand, ...
  int max_hypotheses = 6;       ///< as detect.search.max_hypotheses (at most that), ...
};

/// \brief All parameters of the detector.
struct DetectorParams {
  ViewRange views;
  TemplateParams templates;
  SearchParams search;
  VerifyParams verify;
  ColourParams colour;
};

/// The view range with automatic distances filled in for a model (`radius`: of its bounding
/// sphere about the bounding box centre, metres) and a camera's focal length `focal_px`.
ViewRange resolve_view_range(const ViewRange& v, double radius, double focal_px);

/// Registers every detector parameter under `detect.*` (units and ranges) in `r`; `p` must
/// outlive the registry.
void add_params(ParamRegistry& r, DetectorParams& p);

/// Checks the parameters together (min below max, enough features): an error names the field.
Expected<void> validate(const DetectorParams& p);

}  // namespace v4r::detection
