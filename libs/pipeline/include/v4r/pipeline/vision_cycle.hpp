// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <memory>

#include "v4r/core/clock.hpp"
#include "v4r/core/thread_team.hpp"
#include "v4r/pipeline/budget_planner.hpp"
#include "v4r/pipeline/camera_image.hpp"
#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/pipeline/cycle_report.hpp"
#include "v4r/pipeline/measure_context.hpp"
#include "v4r/pipeline/object_measurer.hpp"
#include "v4r/pipeline/view_predictor.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief The vision cycle of the paper (2.3): per frame, predict every object (EKF); per camera
/// predict what each view can see (other objects hide what is behind them); keep the time
/// budget; then per object measure every view with the measurement units (lines, arcs,
/// junctions), solve T_ref_obj from the observations of all cameras in one adjustment
/// (ObjectSolver), re-measure what was missed from the fresh pose, test the image evidence and
/// update the filter and the status (update_object). The cycle only orchestrates; the units do
/// the work. With CycleParams::threads > 1 the measurement (step 3) runs on a ThreadTeam: the
/// objects in parallel, or one object's views (cameras) when it is the only one tracked; each
/// thread has its own ObjectMeasurer, and the results are those of one thread. Allocates only
/// when the scene grew since the last call; never throws.
class VisionCycle {
 public:
  /// `now` is the clock used for timing and the budget (injectable for tests).
  explicit VisionCycle(const CycleParams& params = {}, Clock::time_point (*now)() = &Clock::now);
  [[nodiscard]] const CycleParams& params() const { return p_; }
  /// The report of the last process() call.
  [[nodiscard]] const CycleReport& last_report() const { return report_; }
  /// Replaces the parameters (rebuilds the units: allocates; not for the real-time path).
  void set_params(const CycleParams& params);

  /// Runs one cycle on one image set per camera of the scene, in order. `stamp_s` is the time of
  /// the images in seconds (negative: frame count * frame_interval_s). A camera without an image
  /// (empty grey view) this cycle contributes nothing.
  const CycleReport& process(scene::Scene& scene, std::span<const CameraImage> images, double stamp_s = -1.0);

  /// Test seam: called with each tracked object at the start of its measurement. Whatever it
  /// throws is handled as a fault in that object's cycle (ObjectReport::failed). Empty by default.
  /// With threads > 1 it is called from the cycle's threads, for different objects at once.
  void set_object_hook(std::function<void(const scene::Object&)> hook) { object_hook_ = std::move(hook); }

  /// Edge pixels found in the last cycle, for overlays (pixels, per camera).
  [[nodiscard]] const std::vector<Eigen::Vector2d>& edgels(std::size_t camera) const;

 private:
  void prepare(const scene::Scene& scene);
  void predict_object(scene::Object& obj, ObjectReport& rep, double stamp_s);
  void predict_views(scene::Scene& scene, std::span<const CameraImage> images);
  /// Step 3 for object oi on unit `unit` (a failure is caught and reported for that object).
  void measure_object(scene::Scene& scene, std::span<const CameraImage> images, std::size_t oi, std::size_t unit,
                      double stamp_s);
  void object_failed(scene::Object& obj, ObjectReport& rep, const char* what) const;

  CycleParams p_;
  Clock::time_point (*now_)();
  std::function<void(const scene::Object&)> object_hook_;
  ViewPredictor predictor_;
  BudgetPlanner budget_;
  BudgetPlan plan_;
  MeasureContext ctx_;
  // Step 3: one measurement unit per thread (CycleParams::threads), the threads, and the objects
  // measured this frame.
  std::vector<std::unique_ptr<ObjectMeasurer>> units_;
  std::vector<ObjectMeasurer*> unit_ptrs_;
  std::unique_ptr<ThreadTeam> team_;
  std::vector<std::size_t> measured_;
  std::vector<std::vector<Eigen::Vector2d>> edgels_;  // per camera, of every unit
  CycleReport report_;
  std::int64_t frame_ = 0;
};

}  // namespace v4r::pipeline
