// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "v4r/estimation/pose_solver.hpp"
#include "v4r/features/line_tracker.hpp"
#include "v4r/image/image_view.hpp"
#include "v4r/pipeline/visibility.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief Every parameter of the vision cycle, with defaults in code (units in the names' docs).
struct CycleParams {
  features::LineTrackerParams track;   ///< window of features found in the last frame
  int search_half_width = 16;          ///< pixels: half width of the window of features not found (yet)
  estimation::PoseSolverParams solver;
  VisibilityParams visibility;
  double line_sigma_px = 0.5;          ///< a-priori noise of a tracked line, pixels
  int min_lines = 4;                   ///< fewer found lines than this: the view pose is not updated
  double degraded_ratio = 0.5;         ///< used / visible below this: status degraded
  int refine_passes = 2;               ///< track + solve passes per frame (later ones re-measure missed features from the new pose)
  double ambiguity_angle = 0.2;        ///< radians: edges closer than this in image direction count as parallel
  double ambiguity_margin_px = 2.0;    ///< parallel edges closer than track.half_width + this are ambiguous
  double ambiguity_min_overlap = 0.2;  ///< ... if they overlap by this fraction of the shorter one
};

/// \brief What one cycle did for one object.
struct ObjectReport {
  scene::TrackStatus status = scene::TrackStatus::kUninitialised;
  int features_visible = 0;
  int features_found = 0;
  int features_used = 0;   ///< inliers of the pose solve
  int outliers = 0;
  double rms_px = 0.0;
  double quality = 0.0;
  int iterations = 0;
};

/// \brief Per-cycle report: per-stage times and one ObjectReport per object.
struct CycleReport {
  std::int64_t frame = 0;
  double cycle_ms = 0.0;
  double visibility_ms = 0.0;  ///< predict + visibility + projection
  double track_ms = 0.0;       ///< feature search and tracking
  double solve_ms = 0.0;       ///< pose estimation and view fusion
  std::vector<ObjectReport> objects;
};

/// \brief The vision cycle of the paper (2.3), per frame and object: predict the pose; for every
/// view, decide visibility and project the model edges; search features not found yet (wide
/// window) and track found ones (tracking window) at their projection; solve the view pose from
/// all found features with outlier removal; fuse the view poses into the object pose.
class VisionCycle {
 public:
  explicit VisionCycle(const CycleParams& params = {});
  [[nodiscard]] const CycleParams& params() const { return p_; }

  /// Runs one cycle on `images` (one 8-bit grey image per camera of the scene, in order).
  /// Allocates only when the scene grew since the last call. Never throws.
  const CycleReport& process(scene::Scene& scene, std::span<const image::ImageView> images);

  /// Edge pixels found in the last cycle, for overlays (pixels, per camera).
  [[nodiscard]] const std::vector<Eigen::Vector2d>& edgels(std::size_t camera) const;

 private:
  void prepare(const scene::Scene& scene);
  void process_view(scene::Object& obj, scene::View& view, const scene::Camera& cam, const image::ImageView& img,
                    ObjectReport& rep);
  void mark_ambiguous(scene::View& view, const scene::Camera& cam) const;
  int track_features(scene::View& view, const scene::Camera& cam, const image::ImageView& img, bool first_pass);

  CycleParams p_;
  features::LineTracker tracker_, searcher_;
  estimation::PoseSolver solver_;
  VisibilityTester visibility_;
  std::vector<EdgeVisibility> edge_vis_;
  std::vector<estimation::LineObservation> line_obs_;
  std::vector<std::uint32_t> line_obs_feature_;
  std::vector<std::uint8_t> line_inlier_;
  std::vector<std::vector<Eigen::Vector2d>> edgels_;
  std::vector<Eigen::Vector2d> undistorted_;  // edge pixels of one feature, normalised
  CycleReport report_;
  std::int64_t frame_ = 0;
};

}  // namespace v4r::pipeline
