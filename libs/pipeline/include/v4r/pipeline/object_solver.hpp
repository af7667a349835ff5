// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include "v4r/estimation/pose_solver.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/pipeline/observation_buffer.hpp"

namespace v4r::pipeline {

/// \brief The outcome of one object solve.
struct ObjectSolve {
  bool updated = false;     ///< the pose was measured (enough observations, the solve converged)
  bool prior_used = false;  ///< some directions were held by the prediction (partial observability)
  geometry::SE3 T_ref_obj;  ///< the measured pose (when updated)
  /// Information of the observations alone, without the prior (reference frame, left tangent;
  /// m^-2, rad^-2): nearly singular in the directions the features do not fix.
  geometry::Matrix6d information = geometry::Matrix6d::Zero();
  /// The reported covariance is `information`^-1 times this: the solve's a-posteriori variance
  /// factor with the report's floor (CycleParams::report_min_sigma0) instead of the solver's
  /// (which protects the filter): (max(sigma0, report floor) / max(sigma0, min_sigma0))^2.
  double report_scale = 1.0;
  /// The solve's sandwich covariance (PoseResult::sandwich_covariance; zero: none): the
  /// reported covariance covers it too (CycleParams::report_sandwich).
  geometry::Matrix6d sandwich = geometry::Matrix6d::Zero();
  estimation::PoseResult result;  ///< the last solve (its T_cam_obj is T_ref_obj)
};

/// \brief The prediction an object solve may lean on (CycleParams::prior_fallback).
struct SolvePrior {
  bool usable = false;        ///< the object's pose was measured since it was set, and a covariance exists
  geometry::SE3 T_ref_obj;    ///< the prediction
  geometry::Matrix6d covariance = geometry::Matrix6d::Zero();  ///< its covariance (reference frame)
};

/// \brief Object-space least squares over the observations of every camera that sees the object
/// (paper 5: Wunsch's solve with outlier removal; one adjustment for all views): solves T_ref_obj
/// from the buffer; when the features do not fix the pose (fewer than min_lines observations,
/// a degenerate set, or a solve whose RMS exceeds prior_max_rms_px), solves again with the
/// prediction as a prior. Writes the inlier flags into the buffer. Allocates only in reserve().
class ObjectSolver {
 public:
  explicit ObjectSolver(const CycleParams& p) : p_(p), solver_(p.solver) {}
  void reserve(std::size_t points, std::size_t lines, std::size_t circles) { solver_.reserve(points, lines, circles); }
  /// Solves from T_init (reference frame).
  ObjectSolve solve(const geometry::SE3& T_init, ObservationBuffer& obs, const SolvePrior& prior);

 private:
  CycleParams p_;
  estimation::PoseSolver solver_;
  estimation::PosePrior prior_;
};

}  // namespace v4r::pipeline
