// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <memory>

#include "v4r/pipeline/object_search.hpp"
#include "v4r/pipeline/vision_cycle.hpp"

namespace v4r::pipeline {

/// \brief The result of one frame for the tracked object.
struct FrameResult {
  geometry::SE3 T_cam_obj;           ///< measured pose (or the prediction when lost)
  geometry::SE3 T_cam_obj_filtered;  ///< EKF output
  geometry::Vector6d velocity = geometry::Vector6d::Zero();  ///< EKF velocity (v, w): m/s, rad/s
  /// Covariance of T_cam_obj: (translation m, rotation rad as a small left rotation), camera
  /// frame; see geometry::translation_rotation_covariance.
  geometry::Matrix6d covariance = geometry::Matrix6d::Zero();
  ObjectReport report;  ///< report.status: after the search (kSearching: no pose this frame)
  SearchReport search;  ///< what the search did this frame (with enable_search)
  double cycle_ms = 0.0;  ///< the cycle's time plus the search's (search.search_ms)
  double visibility_ms = 0.0, track_ms = 0.0, solve_ms = 0.0;
  int degrade_level = 0;
  std::int64_t overruns = 0;
};

/// \brief Convenience front end for the common case of one object seen by one camera whose
/// frame is the reference frame: a Scene with one camera and one object, driven by a VisionCycle.
class SingleObjectTracker {
 public:
  SingleObjectTracker(std::shared_ptr<const model::Model> model, const geometry::PinholeCamera& cam,
                      const CycleParams& params = {});
  /// Sets the object pose (T_cam_obj) and (re)starts tracking from it.
  void set_pose(const geometry::SE3& T_cam_obj);
  /// Lets the object be found without a pose and again after loss (issue 10): `templates` are
  /// the detector's for this model and camera (detection::load_or_build with `dp`). Allocates.
  void enable_search(std::shared_ptr<const detection::TemplateSet> templates, const ObjectSearchParams& sp,
                     const detection::DetectorParams& dp);
  /// Lets the search start from an AprilTag fixed on the object (after enable_search; see
  /// ObjectSearch::set_tag_start).
  void set_tag_start(std::unique_ptr<detection::TagStart> tag);
  /// Starts the object without a pose: it is `searching` until found (needs enable_search).
  void start_search();
  /// Runs one vision cycle on an 8-bit grey image (and optionally the BGR colour image) of the
  /// camera taken at `stamp_s` seconds (negative: frames are frame_interval_s apart).
  FrameResult track(const image::ImageView& grey, const image::ColourView& colour = {}, double stamp_s = -1.0);

  scene::Scene& scene() { return scene_; }
  VisionCycle& cycle() { return cycle_; }

 private:
  scene::Scene scene_;
  VisionCycle cycle_;
  std::unique_ptr<ObjectSearch> search_;
};

}  // namespace v4r::pipeline
