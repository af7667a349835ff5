// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "v4r/geometry/se3.hpp"

namespace v4r::estimation {

/// \brief A 2-D image point matched to a model point. Discrepancy (Wunsch): the 3-D distance of
/// the model point, in the camera frame, from the line of sight through the image point.
struct PointObservation {
  Eigen::Vector3d X_obj = Eigen::Vector3d::Zero();   ///< model point, object frame, metres
  Eigen::Vector2d xn = Eigen::Vector2d::Zero();      ///< undistorted normalised image coordinates
  double sigma_px = 1.0;                             ///< a-priori image noise, pixels
};

/// \brief A 2-D image line matched to a model edge. Discrepancy (Wunsch): the distances of the
/// edge's two model points, in the camera frame, from the interpretation plane (the plane through
/// the camera centre and the image line).
struct LineObservation {
  Eigen::Vector3d X1_obj = Eigen::Vector3d::Zero(), X2_obj = Eigen::Vector3d::Zero();  ///< edge points, object frame
  Eigen::Vector2d xn1 = Eigen::Vector2d::Zero(), xn2 = Eigen::Vector2d::Zero();  ///< two points of the image line, normalised
  double sigma_px = 1.0;  ///< a-priori noise of the line position across, pixels
};

struct PoseSolverParams {
  double focal_px = 500.0;     ///< converts pixel sigmas to normalised units (set from the camera)
  int max_iterations = 15;     ///< Gauss-Newton iterations per solve
  double step_tolerance = 1e-9;  ///< stop when |delta| (m / rad) falls below
  double outlier_threshold = 3.5;  ///< largest normalised residual allowed (units of sigma)
  int max_outlier_rounds = 50;  ///< cap on remove-one-and-solve-again rounds
  int min_observations = 3;    ///< below this many active observations the solve fails
};

enum class SolveStatus : std::uint8_t { kOk, kTooFewObservations, kDiverged, kDegenerate };

/// \brief Result of a pose solve.
struct PoseResult {
  geometry::SE3 T_cam_obj;
  geometry::Matrix6d covariance = geometry::Matrix6d::Zero();  ///< of the left tangent (v, w): m^2, rad^2
  SolveStatus status = SolveStatus::kTooFewObservations;
  int iterations = 0;       ///< Gauss-Newton iterations in all rounds
  int observations = 0;     ///< points + lines given
  int inliers = 0;          ///< observations kept after outlier removal
  double rms_px = 0.0;      ///< RMS residual of the inliers, converted to pixels
  double sigma0 = 1.0;      ///< a-posteriori standard deviation of unit weight
  [[nodiscard]] bool ok() const { return status == SolveStatus::kOk; }
};

/// \brief Object-space least-squares pose (Wunsch 1997, paper section 5): Gauss-Newton on SE(3)
/// with left updates, residuals weighted by their a-priori sigma converted to object space at the
/// point's depth, a 6x6 covariance as accuracy estimate, and outlier detection that removes the
/// observation with the largest normalised residual and solves again until no gross error is
/// left. Buffers grow only when more observations arrive than ever before (reserve() up front to
/// keep solve() allocation-free).
class PoseSolver {
 public:
  explicit PoseSolver(const PoseSolverParams& params = {}) : p_(params) {}
  void reserve(std::size_t points, std::size_t lines);
  PoseSolverParams& params() { return p_; }

  /// Solve from `T_init`. `point_inlier` / `line_inlier`, when non-empty, must have the sizes of
  /// the observation spans and receive 1 for kept and 0 for rejected observations.
  PoseResult solve(const geometry::SE3& T_init, std::span<const PointObservation> points,
                   std::span<const LineObservation> lines, std::span<std::uint8_t> point_inlier = {},
                   std::span<std::uint8_t> line_inlier = {});

 private:
  PoseSolverParams p_;
  std::vector<std::uint8_t> active_pts_, active_lines_;
  std::vector<Eigen::Vector3d> line_normals_;
};

}  // namespace v4r::estimation
