// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/params.hpp"

namespace v4r::pipeline {

ParamRegistry make_registry(CycleParams& p) {
  ParamRegistry r;
  // Line tracking windows (paper 3.1, 3.4).
  auto& t = p.track;
  r.add("track.rows", &t.rows, 3, 256, "", "samples along an edge (fixed window height; long edges subsampled)");
  r.add("track.half_width", &t.half_width, 2, 64, "px", "tracking window half width across the edge");
  r.add("track.end_margin", &t.end_margin, 0.0, 0.45, "", "fraction of an edge left out at each end");
  r.add("track.min_gradient", &t.min_gradient, 0.0, 255.0, "grey/px", "absolute floor of an edge pixel's gradient");
  r.add("track.gradient_noise_factor", &t.gradient_noise_factor, 0.0, 20.0, "",
        "edge pixels exceed this times the window's noise level (threshold follows noise and texture)");
  r.add("track.profile_noise_factor", &t.profile_noise_factor, 0.0, 20.0, "",
        "noise level also from the gradient's deviation from the rows' shared profile, times this (a blurred edge is not noise; 0: off)");
  r.add("track.ramp_min_width", &t.ramp_min_width, 0, 100, "px",
        "a gradient plateau this wide (a blurred edge) is located at its centroid, once (0: off)");
  r.add("track.pair_min_ratio", &t.pair_min_ratio, 0.0, 1.0, "",
        "a pair's two edges make its centre when the weaker is at least this fraction of the stronger (cycle.pair_span)");
  r.add("track.min_relative_strength", &t.min_relative_strength, 0.0, 1.0, "",
        "inliers weaker than this fraction of the line's mean strength are left out of the fit");
  r.add("track.use_colour_gradient", &t.use_colour_gradient,
        "colour input: search a window again on the colour gradient when the grey one shows no edge");
  r.add("track.max_candidates_per_row", &t.max_candidates_per_row, 1, 16, "", "edge pixel candidates kept per row");
  r.add("track.ransac_iterations", &t.ransac_iterations, 1, 10000, "", "RANSAC hypotheses per line");
  r.add("track.inlier_tolerance", &t.inlier_tolerance, 0.05, 10.0, "px", "RANSAC inlier distance");
  r.add("track.min_inlier_ratio", &t.min_inlier_ratio, 0.05, 1.0, "", "rows with an inlier for a line to count as found");
  r.add("track.max_angle", &t.max_angle, 0.01, 1.5, "rad", "largest angle of a fitted line to its window");
  r.add("search.half_width", &p.search_half_width, 2, 128, "px", "window half width for features not found in the last frame");
  r.add("search.backoff_frames", &p.search_backoff_frames, 0, 1000, "frames",
        "missed this long (while tracking well), a feature is searched only every backoff_period frames; 0: always");
  r.add("search.backoff_period", &p.search_backoff_period, 1, 100, "frames", "period of the search of long-missed features");
  // Ellipses (paper 3.2).
  auto& el = p.ellipse;
  r.add("ellipse.half_length", &el.half_length, 2, 64, "px", "tracking line half length across an ellipse");
  r.add("ellipse.min_gradient", &el.min_gradient, 0.0, 255.0, "grey/px", "weakest ellipse edge point gradient");
  r.add("ellipse.ransac_iterations", &el.ransac_iterations, 1, 10000, "", "RANSAC hypotheses per ellipse");
  r.add("ellipse.inlier_tolerance", &el.inlier_tolerance, 0.05, 10.0, "px", "RANSAC inlier distance");
  r.add("ellipse.min_inlier_ratio", &el.min_inlier_ratio, 0.05, 1.0, "", "tracking lines with an inlier for an ellipse to count as found");
  r.add("ellipse.samples", &p.circle_samples, 8, 64, "", "tracking lines per full circle");
  r.add("ellipse.max_points", &p.circle_max_points, 3, 64, "", "edge points per ellipse given to the pose solver");
  r.add("ellipse.sigma", &p.circle_sigma_px, 0.01, 20.0, "px", "a-priori noise of an ellipse edge point");
  r.add("ellipse.min_cos", &p.circle_min_cos, 0.0, 1.0, "", "circles seen more edge-on than this are not tracked");
  // Cue integration (paper 4.1).
  r.add("track.use_cues", &t.use_cues, "check edge pixels against the learned appearance of the object side");
  r.add("track.appearance_k", &t.appearance_k, 0.5, 20.0, "sigma", "appearance tolerance");
  r.add("track.appearance_min_sigma", &t.appearance_min_sigma, 0.0, 128.0, "grey", "floor of the intensity deviation");
  r.add("track.learning_rate", &t.learning_rate, 0.0, 1.0, "", "weight of the current frame in the learned appearance");
  // Junctions (paper 3.3).
  r.add("junction.enabled", &p.use_junctions, "intersect tracked edges at model junctions");
  r.add("junction.min_angle", &p.junction_min_angle, 0.0, 1.5707963, "rad", "smallest angle between intersected edges");
  r.add("junction.sigma_scale", &p.junction_sigma_scale, 0.1, 100.0, "", "junction sigma = line sigma * this / sin(angle)");
  r.add("junction.tangent_tol", &p.tangent_junction_tol_px, 0.1, 20.0, "px",
        "a line-arc junction with a common tangent is valid when the measured line passes this close to the ellipse's tangent point");
  r.add("junction.tangent_sigma_scale", &p.tangent_junction_sigma_scale, 0.1, 100.0, "",
        "tangent junction sigma = line sigma * this");
  // Pose (paper 5).
  auto& s = p.solver;
  r.add("solver.line_sigma", &p.line_sigma_px, 0.01, 20.0, "px", "a-priori noise of a tracked line");
  r.add("solver.max_iterations", &s.max_iterations, 1, 200, "", "Gauss-Newton iterations per solve");
  r.add("solver.step_tolerance", &s.step_tolerance, 0.0, 1.0, "m|rad", "convergence: smallest step");
  r.add("solver.outlier_threshold", &s.outlier_threshold, 1.0, 100.0, "sigma", "largest standardised residual kept");
  r.add("solver.max_outlier_rounds", &s.max_outlier_rounds, 0, 1000, "", "remove-one-and-solve rounds (0: none)");
  r.add("solver.robust_init", &s.robust_init, "Cauchy IRLS pass before outlier removal");
  r.add("solver.cauchy_c", &s.cauchy_c, 0.5, 20.0, "sigma", "Cauchy constant of the robust pass");
  r.add("solver.adaptive_threshold", &s.adaptive_threshold, "widen the outlier threshold when sigma is too optimistic");
  r.add("solver.min_sigma0", &s.min_sigma0, 0.0, 10.0, "", "floor of the a-posteriori scale of the covariance");
  r.add("solver.report_sandwich", &p.report_sandwich,
        "the reported covariance also covers the solve's sandwich covariance (each observation's spread from its own residual)");
  r.add("solver.report_min_sigma0", &p.report_min_sigma0, 0.0, 10.0, "",
        "floor of the a-posteriori scale of the reported covariance");
  // Visibility.
  auto& v = p.visibility;
  r.add("visibility.appear_angle", &v.appear_angle, 0.0, 1.5707963, "rad", "a hidden face appears below this view angle");
  r.add("visibility.disappear_angle", &v.disappear_angle, 0.0, 1.5707963, "rad", "a visible face disappears above this view angle");
  r.add("visibility.grazing_angle", &v.grazing_angle, 1.0, 3.0, "rad", "hidden faces below this may show as slivers");
  r.add("visibility.crease_angle", &v.crease_angle, 0.0, 1.0, "rad", "edges between faces closer than this in normal are dropped");
  r.add("visibility.samples", &v.samples, 2, 256, "", "points per edge tested for occlusion");
  r.add("visibility.occluder_margin", &v.occluder_margin, 0.0, 1.0, "m",
        "another object hides a point only when in front of it by more than this (objects in contact)");
  r.add("visibility.image_margin", &v.image_margin, 0.0, 100.0, "px", "edge parts nearer the border are cut");
  r.add("visibility.min_length", &v.min_length_px, 1.0, 1000.0, "px", "shortest visible edge part tracked");
  // Cycle.
  r.add("cycle.min_lines", &p.min_lines, 3, 1000, "", "fewer found lines: the pose is not updated");
  r.add("cycle.degraded_ratio", &p.degraded_ratio, 0.0, 1.0, "", "used/visible below this: the measurement counts as weak (wider search, gated)");
  r.add("cycle.prior_fallback", &p.prior_fallback,
        "features that fix fewer than 6 dof: solve with the prediction as prior (degraded, not lost)");
  r.add("cycle.prior_max_rms", &p.prior_max_rms_px, 0.1, 1000.0, "px",
        "a solve without prior whose RMS residual exceeds this is redone with the prediction as prior");
  r.add("cycle.refine_passes", &p.refine_passes, 1, 5, "", "track+solve passes per frame");
  r.add("cycle.joint_solve", &p.joint_solve,
        "solve an object's pose from the observations of all cameras in one adjustment (false: per view, then fused)");
  r.add("cycle.threads", &p.threads, 1, 16, "",
        "threads of the vision cycle: objects (or one object's camera views) measured in parallel");
  r.add("cycle.ambiguity_angle", &p.ambiguity_angle, 0.0, 1.0, "rad", "edges closer than this in direction count as parallel");
  r.add("cycle.ambiguity_margin", &p.ambiguity_margin_px, -100.0, 100.0, "px", "parallel edges nearer than half_width + this are side by side");
  r.add("cycle.converging_px", &p.converging_px, 0.0, 100.0, "px",
        "a short edge that stays this close to a longer edge from a shared junction over its whole length is left out (0: off)");
  r.add("cycle.track_side_by_side", &p.track_side_by_side,
        "track side-by-side edges in split windows or as one mid-line edge; false: leave both out");
  r.add("cycle.pair_span", &p.pair_span_px, 0.0, 1000.0, "px",
        "a pair tracked as one across a thin face is measured at the centre between its two edges, found at most this far apart (0: its visible edge)");
  r.add("cycle.pair_thin", &p.pair_thin, 0.0, 100.0, "",
        "... a thin face: the pair's distance in the model at most this share of its edges' length");
  r.add("cycle.split_min_px", &p.split_min_px, 0.5, 1000.0, "px",
        "side-by-side edges get windows split half way when each keeps this much room; else they are ambiguous");
  r.add("cycle.ambiguity_min_overlap", &p.ambiguity_min_overlap, 0.0, 1.0, "", "overlap (fraction) for ambiguity");
  // Time budget (paper 3.4).
  r.add("budget.cycle_ms", &p.budget.cycle_ms, 0.0, 10000.0, "ms", "cycle time budget (0: none)");
  r.add("budget.cost_per_sample_us", &p.budget.cost_per_sample_us, 0.001, 1000.0, "us", "predicted cost of one window row");
  r.add("budget.adapt", &p.budget.adapt, "learn the cost per sample from measured times");
  r.add("budget.reduced_rows", &p.budget.reduced_rows, 3, 256, "", "rows per window when degraded");
  r.add("budget.reserve_fraction", &p.budget.reserve_fraction, 0.0, 0.9, "", "part of the budget kept for pose and filter");
  // Recovery.
  r.add("recovery.max_search_level", &p.recovery.max_search_level, 0, 8, "", "search windows grow to (1 + level) x search.half_width");
  r.add("recovery.lost_quality", &p.recovery.lost_quality, 0.0, 1.0, "", "feature quality below this: the measurement is not used");
  r.add("recovery.reset_velocity_after", &p.recovery.reset_velocity_after, 1, 1000, "frames", "bad frames before the velocity is dropped");
  r.add("recovery.gate_chi2", &p.recovery.gate_chi2, 1.0, 1e9, "", "degraded measurements further from the prediction are rejected");
  r.add("recovery.jump_chi2", &p.recovery.jump_chi2, 0.0, 1e9, "",
        "measurements further from the prediction are used but reported degraded, not tracking (0: no test)");
  // Status from image evidence.
  auto& st = p.status;
  r.add("status.tracking_evidence", &st.tracking_evidence, 0.0, 1.0, "",
        "share of the projected model's edge samples confirmed by the image for status tracking");
  r.add("status.lost_evidence", &st.lost_evidence, 0.0, 1.0, "", "below this share: status lost");
  r.add("status.return_evidence", &st.return_evidence, 0.0, 1.0, "", "a lost object stays lost until this share is confirmed again");
  r.add("status.leak_rate", &st.leak_rate, 0.0, 1.0, "",
        "weight of a tracking frame in the running mean of the silhouette leak (the search's reference)");
  r.add("status.leak_learn_evidence", &st.leak_learn_evidence, 0.0, 1.0, "",
        "the running mean of the silhouette leak learns from tracking frames with this evidence at least");
  r.add("status.leak_period", &st.leak_period, 1, 1000, "frames",
        "the silhouette leak is sampled every this many frames of an object (and the first after its pose is set)");
  r.add("status.leak_margin", &st.leak_margin, 0.0, 1.0, "",
        "the search refuses a pose whose outline leaks the object's colours more than while tracked, by this share (1: off)");
  r.add("status.leak_max_typical", &st.leak_max_typical, 0.0, 1.0, "",
        "the leak test is used for objects whose outline leaks at most this share while tracked");
  r.add("status.leak_min_samples", &st.leak_min_samples, 1, 100000, "", "colour samples the leak test needs");
  // The per-sample measurement beside the line windows (issue 8).
  auto& sm = p.samples;
  r.add("samples.enabled", &sm.enabled,
        "measure the pose also by edge samples searched along their normals from the prediction (moving-edge style); kept when the image confirms it better than the line solve's");
  r.add("samples.always", &sm.always,
        "every frame; else only when the line solve left a visible edge unused (missed or rejected; circles with samples.arcs_doubt)");
  r.add("samples.arcs_doubt", &sm.arcs_doubt, "without samples.always: a visible circle left unused is a doubt too");
  r.add("samples.recent_frames", &sm.recent_frames, 0, 100000, "frames",
        "without samples.always: a visible edge missed for longer than this leaves no doubt (0: however long)");
  r.add("samples.doubt_evidence", &sm.doubt_evidence, 0.0, 1.0, "",
        "without samples.always: a line solve whose edge samples the image confirms at this share or more leaves no doubt (1: "
        "whatever the share)");
  r.add("samples.range", &sm.range_px, 0.5, 32.0, "px", "search range and Tukey width along a sample's normal");
  r.add("samples.iterations", &sm.iterations, 1, 100, "", "Gauss-Newton iterations at most, each searching again");
  r.add("samples.converged", &sm.converged_px, 0.0, 10.0, "px", "the iterations stop when a step moves the model by less than this in the image");
  r.add("samples.spacing", &sm.spacing_px, 1.0, 50.0, "px", "spacing of the edge samples along the projected edges");
  r.add("samples.max_samples", &sm.max_samples, 16, 100000, "", "edge samples per object at most (its views share them equally)");
  r.add("samples.same_px", &sm.same_px, 0.0, 100.0, "px",
        "a per-sample pose that moves the model by less than this from the line solve's is not compared (it changes nothing)");
  r.add("samples.margin", &sm.margin, 0.0, 1.0, "",
        "its pose replaces the line solve's when its share of confirmed edge samples is higher by this");
  r.add("status.contrast_match_share", &st.contrast.match_share, 0.0, 1.0, "",
        "an outside colour sample leaks when this share of the inside samples is alike");
  r.add("status.sample_step", &st.evidence.step_px, 1.0, 100.0, "px", "spacing of the evidence samples along projected edges");
  r.add("status.max_samples_per_edge", &st.evidence.max_samples_per_edge, 1, 1000, "", "evidence samples per edge at most");
  r.add("status.search", &st.evidence.search_px, 0, 8, "px", "an evidence sample looks for its edge this far across");
  r.add("status.max_angle", &st.evidence.max_angle_rad, 0.01, 1.5, "rad", "largest gradient angle to the predicted edge normal");
  r.add("status.min_gradient", &st.evidence.min_gradient, 0.0, 255.0, "grey/px", "floor of the evidence gradient threshold");
  // Temporal filter.
  r.add("filter.enabled", &p.use_filter, "predict and smooth with the constant-velocity EKF");
  r.add("filter.accel_noise", &p.filter.accel_noise, 0.0, 1000.0, "m/s^2", "white-noise acceleration (translation)");
  r.add("filter.angular_accel_noise", &p.filter.angular_accel_noise, 0.0, 1000.0, "rad/s^2", "white-noise angular acceleration");
  r.add("filter.smooth_output", &p.smooth_output,
        "report the pose of a smoother whose process noise adapts to the motion (an object at rest is reported at rest)");
  r.add("filter.min_noise_scale", &p.filter.min_noise_scale, 0.0, 1.0, "", "smoother: smallest scale of its process noise");
  r.add("filter.noise_decay", &p.filter.noise_decay, 0.0, 1.0, "", "smoother: noise scale factor per update that shows no motion");
  r.add("filter.motion_chi2", &p.filter.motion_chi2, 0.0, 1e6, "", "smoother: innovation chi^2 (6 dof) that shows motion: full noise at once");
  r.add("filter.consistency_rate", &p.consistency_rate, 0.0, 1.0, "",
        "weight of each frame's pose jitter (chi^2 / 6 of the third difference of 4 measured poses) in the running mean that scales the reported covariance (0: off)");
  r.add("filter.consistency_max_scale", &p.consistency_max_scale, 1.0, 1e6, "",
        "cap of one frame's term in that mean");
  r.add("filter.image_delay", &p.image_delay_s, 0.0, 1.0, "s",
        "the image shows the object this long before its stamp (half the exposure when stamps mark its end); the pose is reported at the stamp");
  r.add("filter.rest_velocity_chi2", &p.rest_velocity_chi2, 0.0, 1e6, "",
        "smoother: at rest below this velocity chi^2 (6 dof) of the tracking filter (averages), moving above (reports the measurement)");
  r.add("filter.rest_velocity_sigma", &p.rest_velocity_sigma, 0.0, 10.0, "m/s", "smoother: velocity uncertainty of an object at rest");
  r.add("filter.rest_angular_velocity_sigma", &p.rest_angular_velocity_sigma, 0.0, 10.0, "rad/s",
        "smoother: angular velocity uncertainty of an object at rest");
  r.add("filter.frame_interval", &p.frame_interval_s, 1e-4, 10.0, "s", "time between frames without time stamps");
  // Parameters that existed without a name (issue 13: `v4r config` prints every parameter).
  // Not here: ellipse max_samples (from ellipse.samples), solver focal_px (from the camera) and
  // sandwich (from solver.report_sandwich).
  r.add("track.side_offset", &t.side_offset, 0, 32, "px", "from an edge pixel to the first appearance sample across the edge");
  r.add("track.side_width", &t.side_width, 1, 16, "px", "appearance samples on each side of an edge pixel");
  r.add("track.chroma_min_sigma", &t.chroma_min_sigma, 0.0, 1.0, "", "floor of the rg-chromaticity deviation (colour input)");
  r.add("track.shadow_tolerance", &t.shadow_tolerance, 0.0, 10.0, "",
        "colour input: intensity may also differ from the learned mean by this fraction of it");
  r.add("track.learn_min_inlier_ratio", &t.learn_min_inlier_ratio, 0.0, 1.0, "",
        "inlier ratio a fit needs for the appearance to be learned from scratch");
  r.add("track.outside_distinct_k", &t.outside_distinct_k, 0.0, 100.0, "tolerances",
        "colour input, silhouette edges: where the learned outside colour differed from the object side's by this many "
        "tolerances, an edge pixel with the object's colour outside is rejected (a texture line inside the outline; 0: off)");
  r.add("track.share_face_appearance", &p.share_face_appearance,
        "colour input: an edge not found in the last frame is searched with the colour learned on the same face by an edge that was found");
  r.add("track.fallback_keeps_chroma", &t.fallback_keeps_chroma,
        "colour input: when the learned cues leave no edge, the search without them still checks the object side's chromaticity");
  r.add("track.fallback_unchecked", &t.fallback_unchecked,
        "with fallback_keeps_chroma: a search that finds nothing so is repeated without any check");
  r.add("track.colour_before_fallback", &t.colour_before_fallback,
        "colour input: the colour gradient is searched with the learned cues before either gradient is searched without them");
  r.add("ellipse.max_candidates_per_line", &el.max_candidates_per_line, 1, 16, "", "edge point candidates kept per tracking line");
  r.add("ellipse.max_edge_angle", &el.max_edge_angle, 0.01, 1.5707963, "rad", "largest angle of the gradient to the sample normal");
  r.add("solver.min_observations", &s.min_observations, 1, 1000, "", "below this many observations the solve fails");
  r.add("solver.oblique_weighting", &s.oblique_weighting, "exact object-space sigmas for oblique rays");
  r.add("solver.robust_max_iterations", &s.robust_max_iterations, 1, 1000, "", "iterations of the robust (IRLS) pass");
  r.add("solver.robust_step_tolerance", &s.robust_step_tolerance, 0.0, 1.0, "m|rad", "robust pass: smallest step");
  r.add("solver.max_threshold_scale", &s.max_threshold_scale, 1.0, 100.0, "",
        "a robust pass whose noise scale exceeds this is discarded");
  r.add("solver.degeneracy_ratio", &s.degeneracy_ratio, 0.0, 1.0, "", "smallest eigenvalue ratio of a non-degenerate solve");
  r.add("solver.min_depth", &s.min_depth, 1e-9, 10.0, "m", "depth used for the weights of points at or behind the camera");
  r.add("filter.init_velocity_sigma", &p.filter.init_velocity_sigma, 0.0, 100.0, "m/s", "velocity uncertainty after a (re)start");
  r.add("filter.init_angular_velocity_sigma", &p.filter.init_angular_velocity_sigma, 0.0, 100.0, "rad/s",
        "angular velocity uncertainty after a (re)start");
  r.add("filter.reference_dt", &p.filter.reference_dt, 1e-4, 10.0, "s", "frame interval at which the noise levels hold");
  return r;
}

}  // namespace v4r::pipeline
