// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <span>

#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/pipeline/cycle_report.hpp"
#include "v4r/pipeline/object_solver.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief An object's measurement this cycle, all cameras together.
struct ObjectMeasurement {
  int solves = 0;            ///< solves that measured the pose
  bool prior_used = false;   ///< some directions were held by the prediction
  geometry::SE3 T_ref_obj;
  geometry::Matrix6d covariance = geometry::Matrix6d::Zero();  ///< reference frame, left tangent
  /// The covariance reported with the pose (ObjectSolve::report_scale): the same directions, the
  /// solves' own a-posteriori noise level.
  geometry::Matrix6d reported_covariance = geometry::Matrix6d::Zero();
};

/// \brief Combines solves into one measurement: a single solve as it is; several (one per view,
/// CycleParams::joint_solve false) by their information-weighted mean in the tangent space of
/// the first (the paper's view fusion).
ObjectMeasurement combine_solves(std::span<const ObjectSolve> solves);

/// \brief The end of an object's cycle: whether the measurement is used (the share of visible
/// features used, the filter's gate), the filter and smoother updates, the reported pose and
/// covariance, and the status from image evidence (StatusParams). Reads the report's feature
/// counts and the views' evidence; writes the object's state and the report's status.
void update_object(scene::Object& obj, const ObjectMeasurement& m, const CycleParams& p, ObjectReport& rep,
                   double stamp_s);

}  // namespace v4r::pipeline
