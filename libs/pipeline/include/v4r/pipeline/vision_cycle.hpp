// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "v4r/core/clock.hpp"
#include "v4r/estimation/pose_solver.hpp"
#include "v4r/features/edge_evidence.hpp"
#include "v4r/features/ellipse_tracker.hpp"
#include "v4r/features/line_tracker.hpp"
#include "v4r/filter/pose_filter.hpp"
#include "v4r/image/colour_view.hpp"
#include "v4r/image/image_view.hpp"
#include "v4r/pipeline/visibility.hpp"
#include "v4r/scene/scene.hpp"

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
  features::EllipseTrackerParams ellipse;  ///< tracking lines of circle arcs
  int circle_samples = 40;              ///< tracking lines per full circle (fewer for arcs)
  double circle_sigma_px = 0.7;         ///< a-priori noise of an ellipse edge point, pixels
  int circle_max_points = 16;           ///< ellipse edge points per circle handed to the pose solver
  double circle_min_cos = 0.15;         ///< circles seen more edge-on than this (|cos| of view angle) are not tracked
  estimation::PoseSolverParams solver;
  VisibilityParams visibility;
  double line_sigma_px = 0.5;           ///< a-priori noise of a tracked line, pixels
  bool use_junctions = true;            ///< intersect tracked edges at model junctions (paper 3.3)
  double junction_min_angle = 0.35;     ///< radians: smallest angle between edges intersected at a junction
  double junction_sigma_scale = 1.5;    ///< junction sigma = line sigma * this / sin(angle)
  /// Line-arc junctions with a common tangent (paper 3.3): the junction is the point of the
  /// measured ellipse whose tangent is parallel to the measured line, valid when the line passes
  /// within this distance of it (the two edges touch).
  double tangent_junction_tol_px = 1.5;
  double tangent_junction_sigma_scale = 6.0;  ///< its sigma = line sigma * this (weak along the line)
  int min_lines = 4;                    ///< fewer observations than this: the view pose is not updated without a prior
  /// When the features do not fix the pose (fewer than min_lines, or a degenerate set: parallel
  /// edges, one circle), solve with the filter's prediction as a prior: the observed directions
  /// come from the image, the others from the prediction, and the object is `degraded`.
  bool prior_fallback = true;
  double prior_max_rms_px = 3.0;  ///< a solve without prior whose RMS residual exceeds this is redone with it
  double degraded_ratio = 0.5;          ///< used / visible below this: a weak measurement (wider search, gated)
  int refine_passes = 2;                ///< track + solve passes per frame (later ones re-measure missed features from the new pose)
  double ambiguity_angle = 0.2;         ///< radians: edges closer than this in image direction count as parallel
  double ambiguity_margin_px = 2.0;     ///< parallel edges closer than track.half_width + this are side by side
  /// Side-by-side edges (a thin wall seen obliquely) are tracked in windows split half way between
  /// them when each keeps at least this many pixels towards the other; closer ones are ambiguous
  /// and left out. A value above track.half_width leaves every side-by-side pair out.
  double split_min_px = 3.0;
  /// false: side-by-side edges are neither split nor merged but both left out (within the
  /// tracking window's half width + ambiguity_margin_px).
  bool track_side_by_side = true;
  double ambiguity_min_overlap = 0.2;   ///< ... if they overlap by this fraction of the shorter one
  BudgetParams budget;
  RecoveryParams recovery;
  StatusParams status;
  bool use_filter = true;               ///< predict with the EKF (constant velocity); else constant pose
  filter::PoseFilterParams filter;
  /// The reported pose is that of a second filter (Object::smoother) fed the same measurements,
  /// whose process noise adapts (PoseFilterParams::adapt_noise): at rest it averages the
  /// measurements' noise away, a motion restores full noise at once. The tracking filter, which
  /// places the search windows, keeps the full noise. false: the measurement is reported.
  bool smooth_output = true;
  double frame_interval_s = 1.0 / 30.0;  ///< seconds between frames when no time stamps are given
};

/// \brief What one cycle did for one object.
struct ObjectReport {
  scene::TrackStatus status = scene::TrackStatus::kUninitialised;
  int features_visible = 0;
  int features_found = 0;
  int features_used = 0;   ///< observations kept by the pose solve (lines, ellipse points, junctions)
  int outliers = 0;
  int lines_used = 0, circle_points_used = 0, junctions_used = 0;
  int tangent_junctions = 0;  ///< line-arc junctions with a common tangent observed (in junctions_used when inliers)
  double rms_px = 0.0;
  double quality = 0.0;
  double evidence = 0.0;   ///< share of the projected model's edge samples confirmed by the image
  int evidence_samples = 0;
  int iterations = 0;
  int search_level = 0;    ///< 0: normal windows; > 0 searching wider after a bad frame
  bool measurement_rejected = false;  ///< the solve was refused by the filter gate
  bool prior_used = false;  ///< some directions were held by the prediction (partial observability)
  /// The object's cycle threw: the object was taken out of tracking (status kUninitialised, so
  /// later cycles skip it until its pose is set again); `error` says what was thrown.
  bool failed = false;
  std::string error;
};

/// \brief Per-cycle report: per-stage times, budget state and one ObjectReport per object.
struct CycleReport {
  std::int64_t frame = 0;
  double stamp_s = 0.0;
  double cycle_ms = 0.0;
  double visibility_ms = 0.0;  ///< prediction, visibility, projection, ambiguity
  double track_ms = 0.0;       ///< feature search and tracking
  double solve_ms = 0.0;       ///< pose estimation, view fusion and filter
  int degrade_level = 0;       ///< 0 none, 1 fewer samples, 2 features left out
  int features_dropped = 0;    ///< left out by the budget this cycle
  int windows = 0;             ///< feature windows measured (tracking and search, every pass)
  std::int64_t overruns = 0;   ///< cycles so far that took longer than the budget
  std::vector<ObjectReport> objects;
};

/// \brief Images of one camera for one cycle: 8-bit grey, and optionally the BGR colour image
/// (used by cue integration).
struct CameraImage {
  image::ImageView grey;
  image::ColourView colour;  ///< empty if not available
};

/// \brief The vision cycle of the paper (2.3), per frame and object: predict the pose (EKF);
/// for every view decide visibility and project the model edges and circles; search features not
/// found yet (wide window) and track found ones (tracking window) at their projection; intersect
/// tracked edges at junctions; solve the view pose from all features with outlier removal;
/// re-measure what was missed from the fresh pose; fuse the view poses into the object pose and
/// update the filter. Allocates only when the scene grew since the last call; never throws.
class VisionCycle {
 public:
  /// `now` is the clock used for timing and the budget (injectable for tests).
  explicit VisionCycle(const CycleParams& params = {}, Clock::time_point (*now)() = &Clock::now);
  [[nodiscard]] const CycleParams& params() const { return p_; }
  /// The report of the last process() call.
  [[nodiscard]] const CycleReport& last_report() const { return report_; }
  /// Replaces the parameters (rebuilds the trackers: allocates; not for the real-time path).
  void set_params(const CycleParams& params);

  /// Runs one cycle on one image set per camera of the scene, in order. `stamp_s` is the time of
  /// the images in seconds (negative: frame count * frame_interval_s).
  const CycleReport& process(scene::Scene& scene, std::span<const CameraImage> images, double stamp_s = -1.0);

  /// Test seam: called with each tracked object at the start of its measurement. Whatever it
  /// throws is handled as a fault in that object's cycle (ObjectReport::failed). Empty by default.
  void set_object_hook(std::function<void(const scene::Object&)> hook) { object_hook_ = std::move(hook); }

  /// Edge pixels found in the last cycle, for overlays (pixels, per camera).
  [[nodiscard]] const std::vector<Eigen::Vector2d>& edgels(std::size_t camera) const;

 private:
  void prepare(const scene::Scene& scene);
  void predict_view(scene::Object& obj, scene::View& view, const scene::Camera& cam);
  void mark_ambiguous(scene::View& view, const scene::Camera& cam) const;
  void plan_budget(scene::Scene& scene);
  int track_features(const model::Model& model, scene::View& view, const scene::Camera& cam, const CameraImage& img,
                     bool first_pass, int search_level);
  void collect_observations(const scene::Object& obj, scene::View& view, const scene::Camera& cam);
  void add_tangent_junctions(const model::Model& model, const scene::View& view, const scene::Camera& cam);
  void process_view(scene::Object& obj, scene::View& view, const scene::Camera& cam, const CameraImage& img,
                    ObjectReport& rep);
  void measure_evidence(scene::View& view, const scene::Camera& cam, const CameraImage& img);
  void fuse_and_filter(scene::Scene& scene, scene::Object& obj, ObjectReport& rep, double stamp_s);

  void object_failed(scene::Object& obj, ObjectReport& rep, const char* what) const;

  CycleParams p_;
  Clock::time_point (*now_)();
  std::function<void(const scene::Object&)> object_hook_;
  int tangent_junctions_ = 0;  // line-arc tangent junctions observed in the last collect_observations
  int refound_ = 0;  // features missed in the first pass and found by a later one (this call)
  features::LineTracker tracker_, reduced_tracker_;
  std::vector<features::LineTracker> searchers_;  // per search level
  features::EllipseTracker ellipse_tracker_, ellipse_searcher_, reduced_ellipse_tracker_;
  features::EdgeEvidence evidence_;
  estimation::PoseSolver solver_;
  estimation::PosePrior prior_;  // the prediction, when a view needs it
  VisibilityTester visibility_;
  std::vector<EdgeVisibility> edge_vis_;
  std::vector<estimation::LineObservation> line_obs_;
  std::vector<std::uint32_t> line_obs_feature_;
  std::vector<std::uint8_t> line_inlier_;
  std::vector<estimation::PointObservation> point_obs_;
  std::vector<std::uint8_t> point_inlier_;
  std::vector<estimation::CircleObservation> circle_obs_;
  std::vector<std::uint32_t> circle_obs_feature_;
  std::vector<std::uint8_t> circle_inlier_;
  std::vector<features::CurveSample> curve_;
  std::vector<std::vector<Eigen::Vector2d>> edgels_;
  std::vector<Eigen::Vector2d> undistorted_;  // edge pixels of one feature, normalised
  std::vector<float> drop_scores_;            // budget: informativeness per feature
  int degrade_level_ = 0;
  int rows_per_line_ = 0, samples_per_circle_ = 0;
  double last_track_us_ = 0.0;
  long last_samples_ = 0;
  CycleReport report_;
  std::int64_t frame_ = 0;
};

}  // namespace v4r::pipeline
