// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "v4r/estimation/residuals.hpp"
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

/// \brief Settings of PoseSolver. Sigmas and thresholds are in units of the observations' a-priori
/// sigma unless stated otherwise.
struct PoseSolverParams {
  double focal_px = 500.0;     ///< converts pixel sigmas to normalised units (set from the camera)
  int max_iterations = 15;     ///< Gauss-Newton iterations per solve
  double step_tolerance = 1e-9;  ///< stop when |delta| (m / rad) falls below
  double outlier_threshold = 3.5;  ///< largest normalised residual allowed (units of sigma)
  int max_outlier_rounds = 50;  ///< cap on remove-one-and-solve-again rounds (0: no outlier detection)
  int min_observations = 3;    ///< below this many active observations the solve fails
  /// Use the first-order exact object-space sigmas: for a point the radial component of the
  /// discrepancy gets sigma * cos(theta) (ray angle to the optical axis), for a line both plane
  /// distances get sigma * sqrt(1 - n_z^2). false: sigma_px * z / focal_px for everything.
  bool oblique_weighting = true;
  /// Before the remove-largest loop, run an IRLS pass with Cauchy weights (scale estimated from
  /// the 30 % quantile of the residuals) from T_init and reject what it marks as gross errors, so
  /// that they no longer pull the plain solution. The pass is discarded when it would reject more
  /// than half of the observations or its scale exceeds max_threshold_scale.
  bool robust_init = true;
  double cauchy_c = 2.385;          ///< Cauchy constant of the IRLS pass (units of sigma)
  int robust_max_iterations = 30;   ///< iterations of the IRLS pass
  double robust_step_tolerance = 1e-6;  ///< the IRLS pass stops when |delta| (m / rad) falls below
  /// Multiply outlier_threshold by max(1, s_low), s_low a lower confidence bound of the
  /// quantile-based noise scale of the robust pass, so that an a-priori sigma that is too
  /// optimistic does not turn inliers into outliers (only with robust_init).
  bool adaptive_threshold = true;
  /// A robust pass whose (lower-bound) noise scale exceeds this is taken as pulled by gross
  /// errors and discarded (the remove-largest loop starts from T_init with the a-priori threshold).
  double max_threshold_scale = 3.0;
  /// Covariance = max(sigma0, min_sigma0)^2 * H^-1: a-posteriori scaling, but never more than
  /// 1/min_sigma0^2 times tighter than the a-priori covariance (protects a downstream filter when
  /// the redundancy is small and sigma0 happens to come out tiny).
  double min_sigma0 = 0.5;
  double degeneracy_ratio = 1e-10;  ///< min/max eigenvalue of the balanced normal matrix below: kDegenerate
  double min_depth = 1e-3;          ///< depth (m) used for weights of points at or behind the camera
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
  double noise_scale = 1.0;  ///< noise scale found by the robust pass (units of a-priori sigma; 1 without it)
  int outlier_rounds = 0;   ///< observations removed by the remove-largest loop (after the robust pass)
  bool converged = false;   ///< the last Gauss-Newton run reached step_tolerance
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
  /// the observation spans and receive 1 for kept and 0 for rejected observations (spans of any
  /// other size are left untouched). Invalid observations (non-finite values, sigma_px <= 0, two
  /// coincident line points) are rejected up front and flagged 0. Status: kTooFewObservations
  /// below min_observations valid observations or 6 scalar residuals, kDegenerate for a
  /// rank-deficient normal matrix (e.g. all points identical) or focal_px <= 0, kDiverged for a
  /// non-finite T_init or step or a final pose with observed points at or behind the camera. On
  /// failure T_cam_obj is T_init and the covariance zero.
  ///
  /// Flow: optional robust pass (see PoseSolverParams::robust_init), then plain weighted least
  /// squares removing the active observation with the largest standardised residual (residual
  /// over its own standard deviation, I - J H^-1 J^T; for the two scalar residuals of one
  /// observation the RMS) while it exceeds the threshold; once, rejected observations whose
  /// prediction error is within the threshold are re-admitted and the loop repeats.
  PoseResult solve(const geometry::SE3& T_init, std::span<const PointObservation> points,
                   std::span<const LineObservation> lines, std::span<std::uint8_t> point_inlier = {},
                   std::span<std::uint8_t> line_inlier = {});

 private:
  /// Sums of one linearisation in normalised (sigma) units: H = sum rho J^T J, g = sum rho J^T r.
  struct Normal {
    geometry::Matrix6d H = geometry::Matrix6d::Zero();
    geometry::Vector6d g = geometry::Vector6d::Zero();
    double chi2 = 0.0;      ///< sum of squared normalised residuals (unweighted by rho)
    double sum_sq_px = 0.0; ///< sum of squared residuals converted to pixels
    int residuals = 0;      ///< scalar residuals accumulated
    int behind = 0;         ///< active observation points at or behind the camera
  };
  enum class Statistic : std::uint8_t { kPlain, kStandardised };

  void prepare(std::span<const PointObservation> points, std::span<const LineObservation> lines);
  Normal linearise(const geometry::SE3& T, std::span<const PointObservation> points,
                   std::span<const LineObservation> lines, bool robust) const;
  SolveStatus gauss_newton(geometry::SE3& T, std::span<const PointObservation> points,
                           std::span<const LineObservation> lines, bool robust, int max_iterations, int& iterations,
                           bool& converged, Normal& last);
  void update_robust_weights(double scale);
  void statistics(const geometry::SE3& T, const geometry::Matrix6d& H_inv, std::span<const PointObservation> points,
                  std::span<const LineObservation> lines, Statistic kind);
  double quantile_scale();
  int count_active() const;

  PoseSolverParams p_;
  std::vector<std::uint8_t> active_pts_, active_lines_;  ///< 1 active, 0 rejected, 2 invalid input
  std::vector<RayBasis> point_bases_;
  std::vector<Eigen::Vector3d> line_normals_;
  std::vector<double> rho_pts_, rho_lines_;    ///< IRLS weights
  std::vector<double> stat_pts_, stat_lines_;  ///< per-observation test statistic, units of sigma
  std::vector<double> scratch_;                ///< median work buffer
};

}  // namespace v4r::estimation
