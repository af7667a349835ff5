// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include "v4r/estimation/pose_solver.hpp"
#include "v4r/features/edge_evidence.hpp"
#include "v4r/features/silhouette_contrast.hpp"
#include "v4r/features/ellipse_tracker.hpp"
#include "v4r/features/line_tracker.hpp"
#include "v4r/filter/pose_filter.hpp"
#include "v4r/pipeline/visibility.hpp"

namespace v4r::pipeline {

/// \brief Time budget of a cycle (paper 3.4). Window sizes stay fixed; when the visible features
/// would overrun the budget the cycle degrades in this order: (1) fewer samples per edge
/// (`reduced_rows` per line window, half the samples per ellipse), (2) the least informative
/// features are left out (shortest edges first). Cost is predicted from a per-sample cost that
/// is learned from the measured tracking time (or fixed, `adapt = false`).
struct BudgetParams {
  double cycle_ms = 0.0;          ///< milliseconds per cycle; 0 = no budget
  double cost_per_sample_us = 0.6;  ///< predicted tracking cost of one window row / ellipse sample, microseconds
  bool adapt = true;              ///< learn cost_per_sample_us from measured tracking times
  int reduced_rows = 10;          ///< rows per line window at degradation level 1
  double reserve_fraction = 0.25;  ///< part of the budget kept for visibility, pose and filter
};

/// \brief Losing and regaining track: how far to search when a frame goes bad.
struct RecoveryParams {
  int max_search_level = 2;       ///< search windows grow to (1 + level) * search half width
  double lost_quality = 0.15;     ///< feature quality (used/visible, residuals) below this: the measurement is not used
  int reset_velocity_after = 2;   ///< lost frames after which the filter's velocity is dropped
  double gate_chi2 = 400.0;       ///< a degraded measurement this far from the prediction (chi^2, 6 dof) is rejected
  /// A measurement this far from the prediction (chi^2, 6 dof) is a jump the motion so far does
  /// not explain: used, but reported `degraded` (an edge image also fits a wrong pose, under
  /// occlusion or blur), so that a recovery does not start from it. 0: no such test.
  double jump_chi2 = 150.0;
};

/// \brief The status from image evidence: after the solve, samples along the whole projected
/// model (every visible edge and circle, tracked or not) look for a gradient of matching position
/// and orientation (features::EdgeEvidence). The share they find decides what is reported: below
/// lost_evidence the pose is not supported by the image (`lost`); from tracking_evidence on, with
/// a measurement whose features fix every direction, `tracking`; in between, or with directions
/// held by the prediction, `degraded`. (Whether a measurement is used, and how wide the next
/// search is, follows the features: RecoveryParams::lost_quality, CycleParams::degraded_ratio.)
struct StatusParams {
  features::EdgeEvidenceParams evidence;
  double tracking_evidence = 0.5;  ///< share of matched edge samples for `tracking`
  double lost_evidence = 0.2;      ///< below this share: `lost`
  /// An object reported `lost` stays `lost` until this share is confirmed again (hysteresis: a
  /// measurement of the held pose that finds a little of the model is not a return).
  double return_evidence = 0.4;
  features::SilhouetteContrastParams contrast;
  /// Weight of a frame in the running mean of the silhouette leak over frames reported
  /// `tracking` with at least leak_learn_evidence (scene::Object::leak_typical).
  double leak_rate = 0.1;
  double leak_learn_evidence = 0.7;
  /// The silhouette leak is sampled on every leak_period-th frame of an object (and on the first
  /// after its pose is set); between, the cycle takes no colour samples (scene::Object::leak -1).
  /// While tracked it feeds only the running mean, which the search uses after a loss; the
  /// search's own refinement samples every frame.
  int leak_period = 4;
  /// The search refuses a pose whose silhouette leaks more than leak_typical by this share (from
  /// at least leak_min_samples colour samples): its outline lies on the object itself (a pose
  /// nested in the real one, its edges on texture) or on the wrong side of the object.
  double leak_margin = 0.15;
  int leak_min_samples = 12;
  /// ... and only for an object that stands out from its surroundings: leak_typical at most this
  /// (an object whose outline leaks much while tracked looks like its background; no cue).
  double leak_max_typical = 0.25;
};

/// \brief The per-sample measurement of a view's pose, beside the line windows (issue 8: "a
/// per-sample search with a robust M-estimator beside the RANSAC line, as moving-edge trackers
/// do"; pipeline::SampleRefiner). The visible model edges are sampled every `spacing_px`; each
/// sample takes the strongest gradient aligned with its normal within `range_px` along it;
/// Tukey-weighted Gauss-Newton iterations move the pose. It starts from the predicted pose, so a
/// line window that took a texture edge beside the real one does not pull it. Where the line
/// solve leaves doubt (a visible edge rejected or missed), the cycle keeps the samples' pose
/// instead of the line solve's when the image confirms it better (edge evidence, by `margin`).
struct SampleRefineParams {
  bool enabled = true;
  bool always = false;        ///< every frame; else only when the line solve left a visible edge unused
  bool arcs_doubt = false;    ///< ... or circle (off: a blurred circle is often missed, and the samples do not hold it better)
  int recent_frames = 0;      ///< ... rejected, or missed for at most this many frames (0: however long)
  /// ... and only while the image confirms less than this share of the line solve's edge samples
  /// (1: whatever it confirms): a pose it confirms this well leaves the samples' pose little to
  /// gain (on the development benchmark and ViSP's cube none was kept above 0.912).
  double doubt_evidence = 0.92;
  double range_px = 3.0;      ///< search range and Tukey width along a sample's normal
  int iterations = 10;        ///< Gauss-Newton iterations at most (each searches again)
  double converged_px = 0.2;  ///< ... stopped when a step moves the model by less than this in the image
  double spacing_px = 3.0;    ///< spacing of the edge samples along the projected edges
  int max_samples = 300;      ///< edge samples per object at most (its views share them equally)
  double same_px = 0.5;       ///< a pose within this of the line solve's (in the image) is not compared
  double margin = 0.02;       ///< its pose is kept when its edge evidence exceeds the line solve's by this share
};

/// \brief Every parameter of the vision cycle, with defaults in code (units in the docs).
struct CycleParams {
  features::LineTrackerParams track;    ///< window of features found in the last frame
  int search_half_width = 16;           ///< pixels: half width of the window of features not found (yet)
  /// A feature missed for this many frames in a row while the view is tracked normally (search
  /// level 0) is searched only every search_backoff_period-th frame: an edge without contrast in
  /// this view costs no wide window every frame. 0 disables the back-off.
  int search_backoff_frames = 4;
  int search_backoff_period = 4;
  /// Cue integration: the object side of an edge not found in the last frame (coming into view,
  /// lost, never found) takes the colour appearance learned on the same face by an edge that was
  /// found, so that its search rejects edges of other colours; what it learned itself may be stale
  /// or learned from a wrong edge.
  bool share_face_appearance = true;
  features::EllipseTrackerParams ellipse;  ///< tracking lines of circle arcs
  int circle_samples = 40;              ///< tracking lines per full circle (fewer for arcs)
  double circle_sigma_px = 0.7;         ///< a-priori noise of an ellipse edge point, pixels
  int circle_max_points = 16;           ///< ellipse edge points per circle handed to the pose solver
  double circle_min_cos = 0.15;         ///< circles seen more edge-on than this (|cos| of view angle) are not tracked
  estimation::PoseSolverParams solver;
  VisibilityParams visibility;
  double line_sigma_px = 0.5;           ///< a-priori noise of a tracked line, pixels
  /// Floor of the a-posteriori scale of the reported covariance (the solver's min_sigma0 floors
  /// the one the filter uses, higher to keep it cautious).
  double report_min_sigma0 = 0.1;
  /// The reported covariance also covers the solve's sandwich covariance (each observation's
  /// spread taken from its own residual, PoseResult::sandwich_covariance) where that is larger.
  bool report_sandwich = true;
  bool use_junctions = true;            ///< intersect tracked edges at model junctions (paper 3.3)
  double junction_min_angle = 0.35;     ///< radians: smallest angle between edges intersected at a junction
  double junction_sigma_scale = 1.5;    ///< junction sigma = line sigma * this / sin(angle)
  /// Line-arc junctions with a common tangent (paper 3.3): the junction is the point of the
  /// measured ellipse whose tangent is parallel to the measured line, valid when the line passes
  /// within this distance of it (the two edges touch).
  double tangent_junction_tol_px = 1.5;
  double tangent_junction_sigma_scale = 6.0;  ///< its sigma = line sigma * this (weak along the line)
  int min_lines = 4;                    ///< fewer lines (circles: 4 edge points count one) than this: the view pose is not updated without a prior; junctions do not count (they are intersections of the lines)
  /// When the features do not fix the pose (fewer than min_lines, or a degenerate set: parallel
  /// edges, one circle), solve with the filter's prediction as a prior: the observed directions
  /// come from the image, the others from the prediction, and the object is `degraded`.
  bool prior_fallback = true;
  double prior_max_rms_px = 3.0;  ///< a solve without prior whose RMS residual exceeds this is redone with it
  double degraded_ratio = 0.5;          ///< used / visible below this: a weak measurement (wider search, gated)
  int refine_passes = 2;                ///< track + solve passes per frame (later ones re-measure missed features from the new pose)
  /// true: the observations of every camera that sees an object enter one solve of T_ref_obj
  /// (each through its camera's T_ref_cam). false: each view is solved alone and the view poses
  /// are fused by their information (the paper's view fusion; kept for comparison).
  bool joint_solve = true;
  double ambiguity_angle = 0.2;         ///< radians: edges closer than this in image direction count as parallel
  double ambiguity_margin_px = 2.0;     ///< parallel edges closer than track.half_width + this are side by side
  /// A short edge that leaves a junction with a longer (not parallel) edge and stays within this
  /// distance of it over its whole length (length x sin(angle) <= this) is left out (ambiguous):
  /// its window always holds the other edge too (the short side of a face seen at a grazing
  /// angle, beside the face's long crease; at right angles, an edge shorter than this). 0: off.
  double converging_px = 6.0;
  /// Side-by-side edges (a thin wall seen obliquely) are tracked in windows split half way between
  /// them when each keeps at least this many pixels towards the other; closer ones are ambiguous
  /// and left out. A value above track.half_width leaves every side-by-side pair out.
  double split_min_px = 3.0;
  /// false: side-by-side edges are neither split nor merged but both left out (within the
  /// tracking window's half width + ambiguity_margin_px).
  bool track_side_by_side = true;
  /// A pair tracked as one (closer than twice split_min_px) across a thin face is measured at
  /// the centre between its two edges: per window row, the strongest edge of each sign, at most
  /// this many pixels apart (or the pair's predicted separation + 2, if more), give their
  /// midpoint (features::SearchRange::pair_span); motion blur across a thin plate pushes its two
  /// edges apart by the blur's length, their midpoint stays. 0: the pair's visible edge is measured.
  double pair_span_px = 12.0;
  /// ... when the face between them is thin: the edges' distance in the model at most this share
  /// of their length (a plate's edge face; not a box's side seen edge-on, whose texture would
  /// give the window a second edge).
  double pair_thin = 0.25;
  double ambiguity_min_overlap = 0.2;   ///< ... if they overlap by this fraction of the shorter one
  BudgetParams budget;
  RecoveryParams recovery;
  StatusParams status;
  SampleRefineParams samples;  ///< the per-sample measurement beside the line windows
  bool use_filter = true;               ///< predict with the EKF (constant velocity); else constant pose
  filter::PoseFilterParams filter;
  /// The reported pose is that of a second filter (Object::smoother) fed the same measurements,
  /// whose process noise adapts (PoseFilterParams::adapt_noise): at rest it averages the
  /// measurements' noise away, a motion restores full noise at once. The tracking filter, which
  /// places the search windows, keeps the full noise. false: the measurement is reported.
  bool smooth_output = true;
  /// At rest or moving, as the tracking filter's velocity shows (vel^T P_vel^-1 vel, 6 dof;
  /// with the filter's full process noise it stays below 4 for an object at rest under sensor
  /// noise, mostly below 1, and far above for a motion of a millimetre per frame). Below: the smoother
  /// holds its velocity at zero (within rest_velocity_sigma and rest_angular_velocity_sigma)
  /// and averages the measurements; above: it restarts at each measurement, so a moving object
  /// is reported where it is measured, with no lag.
  double rest_velocity_chi2 = 4.0;
  /// Covariance matching: Object::consistency follows the normalised jitter of the measured
  /// poses (chi^2 / 6 of the third difference of four consecutive ones) with this weight (0:
  /// off), each term capped at consistency_max_scale, and the reported covariance is multiplied
  /// by max(1, consistency). A solve's covariance comes from its own residuals, which an error
  /// shared by its lines (a blurred outline, a weak geometry) does not raise; the frame-to-frame
  /// scatter of the poses shows it.
  double consistency_rate = 0.1;
  double consistency_max_scale = 30.0;
  /// Seconds by which the image shows the object before its time stamp: half the exposure when
  /// stamps mark the end of the exposure (0: its middle, or a short exposure). A blurred image is
  /// the object's average over the exposure, so a measured pose is that of the exposure's middle;
  /// the reported pose is moved on to the stamp with the filter's velocity, exp(v delay) T, and
  /// its covariance is multiplied by 1 + 2 (delay / dt)^2 (a velocity from the last two
  /// measurements, dt apart).
  double image_delay_s = 0.0;
  double rest_velocity_sigma = 1e-4;          ///< m/s: velocity of an object at rest
  double rest_angular_velocity_sigma = 1e-3;  ///< rad/s: angular velocity of an object at rest
  double frame_interval_s = 1.0 / 30.0;  ///< seconds between frames when no time stamps are given
  /// Threads of the cycle (the calling one included): objects are measured in parallel, or the
  /// views of an object (one per camera) when only one object is tracked. Results are the same
  /// for any number (each object or view is measured alone); 1 measures everything in turn.
  int threads = 1;
};

}  // namespace v4r::pipeline
