// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <array>
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
  std::uint8_t camera = 0;                           ///< index into ObservationSet::cameras
};

/// \brief A 2-D image line matched to a model edge. Discrepancy (Wunsch): the distances of the
/// edge's two model points, in the camera frame, from the interpretation plane (the plane through
/// the camera centre and the image line).
struct LineObservation {
  Eigen::Vector3d X1_obj = Eigen::Vector3d::Zero(), X2_obj = Eigen::Vector3d::Zero();  ///< edge points, object frame
  Eigen::Vector2d xn1 = Eigen::Vector2d::Zero(), xn2 = Eigen::Vector2d::Zero();  ///< two points of the image line, normalised
  double sigma_px = 1.0;  ///< a-priori noise of the line position across, pixels
  std::uint8_t camera = 0;  ///< index into ObservationSet::cameras
};

/// \brief A 3-D point measured in the camera frame (stereo, range sensor) matched to a model
/// point. Discrepancy: T * X_obj - P_cam (3 components, metres).
struct Point3Observation {
  Eigen::Vector3d X_obj = Eigen::Vector3d::Zero();  ///< model point, object frame, metres
  Eigen::Vector3d P_cam = Eigen::Vector3d::Zero();  ///< measured point, camera frame, metres
  double sigma_m = 0.002;                           ///< a-priori noise per coordinate, metres
  std::uint8_t camera = 0;                          ///< index into ObservationSet::cameras
};

/// \brief The measured surface normal of a model region (e.g. from a fitted plane). Discrepancy:
/// R * n_obj - n_cam by its two components perpendicular to n_cam (radians); rotation only.
struct NormalObservation {
  Eigen::Vector3d n_obj = Eigen::Vector3d::UnitZ();  ///< region normal, object frame (normalised by the solver)
  Eigen::Vector3d n_cam = Eigen::Vector3d::UnitZ();  ///< measured normal, camera frame (normalised by the solver)
  double sigma_rad = 0.02;                           ///< a-priori noise per component, radians
  std::uint8_t camera = 0;                           ///< index into ObservationSet::cameras
};

/// \brief One edge point on the image (an ellipse) of a model circle. Discrepancy in object
/// space: the line of sight through xn meets the circle's plane (camera frame) at X; the residual
/// is |X - centre| - radius (metres), weighted with sigma_px * depth / focal_px times the
/// obliqueness gain of the plane to the ray (see normalised_circle_residual). A ray parallel to
/// the plane or meeting it behind the camera makes the observation unusable at that pose: it is
/// then treated as an outlier.
struct CircleObservation {
  Eigen::Vector3d center_obj = Eigen::Vector3d::Zero();    ///< circle centre, object frame, metres
  Eigen::Vector3d normal_obj = Eigen::Vector3d::UnitZ();   ///< circle axis, object frame (normalised by the solver)
  double radius = 0.0;                                     ///< metres, > 0
  Eigen::Vector2d xn = Eigen::Vector2d::Zero();            ///< edge point, undistorted normalised image coordinates
  double sigma_px = 1.0;                                   ///< a-priori image noise of the edge point, pixels
  std::uint8_t camera = 0;                                 ///< index into ObservationSet::cameras
};

/// \brief A prior on the pose (e.g. a filter's prediction): the pose is taken to be
/// exp(n) * T_cam_obj, n ~ N(0, information^-1), n the left tangent (v, w) in metres and radians.
/// In a solve it adds the 6 residuals U log(T * T_cam_obj^-1) (U^T U = information), so that the
/// directions the observations do not fix (three parallel edges, one circle, one face seen
/// frontally) keep the prior's value instead of making the solve degenerate. It is never an
/// outlier and counts as no observation.
struct PosePrior {
  geometry::SE3 T_cam_obj;
  geometry::Matrix6d information = geometry::Matrix6d::Zero();  ///< m^-2, rad^-2 (symmetric positive definite)
};

/// \brief A camera of a solve over several cameras (paper 5: the views of all cameras in one
/// adjustment). The solved pose is then T_ref_obj, and an observation of camera c sees
/// T_cam_ref * T_ref_obj.
struct SolveCamera {
  geometry::SE3 T_cam_ref;  ///< maps the reference frame (of the solved pose) into the camera
  double focal_px = 0.0;    ///< the camera's focal length (pixel sigmas to normalised units); <= 0: PoseSolverParams::focal_px
};

/// Most cameras one solve takes (observations of a camera beyond are invalid).
inline constexpr std::size_t kMaxSolveCameras = 16;

/// \brief All observations of one solve, by type (any span may be empty).
struct ObservationSet {
  std::span<const PointObservation> points;
  std::span<const LineObservation> lines;
  std::span<const CircleObservation> circles;
  std::span<const Point3Observation> points3d;
  std::span<const NormalObservation> normals;
  /// Optional prior on the pose; with it a solve needs only one valid observation.
  const PosePrior* prior = nullptr;
  /// The cameras the observations come from (their `camera` indexes this). Empty: one camera
  /// whose frame is that of the solved pose (T_cam_obj), focal length from the parameters. At
  /// most kMaxSolveCameras; observations naming a camera that is not given are invalid.
  std::span<const SolveCamera> cameras;
};

/// \brief Optional per-observation inlier outputs of a solve, one span per type of
/// ObservationSet. A span whose size differs from its observation span is left untouched.
struct InlierFlags {
  std::span<std::uint8_t> points, lines, circles, points3d, normals;
};

/// \brief Settings of PoseSolver. Sigmas and thresholds are in units of the observations' a-priori
/// sigma unless stated otherwise. Observations with 1, 2 or 3 scalar residuals (circle edge
/// points; 2-D points, lines, normals; 3-D points) are tested on one scale: each observation's
/// chi-square value with m degrees of freedom is mapped to the RMS of a 2-residual observation
/// with the same tail probability (the identity for m = 2), so a threshold has the same
/// false-alarm rate for every type (3.5: p = 4.8e-6).
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
  /// Compute PoseResult::sandwich_covariance (n more residual evaluations after the solve).
  bool sandwich = true;
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
  int observations = 0;     ///< observations given, all types
  int inliers = 0;          ///< observations kept after outlier removal
  double rms_px = 0.0;      ///< RMS residual of the image inliers (2-D points, lines, circles), in pixels
  double sigma0 = 1.0;      ///< a-posteriori standard deviation of unit weight
  /// Sandwich (heteroscedasticity-consistent, "HC2") covariance of the pose (left tangent, m^2,
  /// rad^2): H^-1 (sum over the inliers of J^T Q^-1/2 r r^T Q^-1/2 J) H^-1, normalised units,
  /// Q = I - J H^-1 J^T the cofactor of the inlier's residual r. It takes each observation's
  /// spread from its own residual instead of one sigma0 for all: unbiased for independent
  /// errors of the a-priori form, and one observation that pulls the pose alone (a background
  /// edge taken for the model's) widens it. Zero with a prior, fewer than 2 inliers or
  /// PoseSolverParams::sandwich off.
  geometry::Matrix6d sandwich_covariance = geometry::Matrix6d::Zero();
  double noise_scale = 1.0;  ///< noise scale found by the robust pass (units of a-priori sigma; 1 without it)
  int outlier_rounds = 0;   ///< observations removed by the remove-largest loop (after the robust pass)
  bool converged = false;   ///< the last Gauss-Newton run reached step_tolerance
  [[nodiscard]] bool ok() const { return status == SolveStatus::kOk; }
};

/// \brief Object-space least-squares pose (Wunsch 1997, paper section 5): Gauss-Newton on SE(3)
/// with left updates over 2-D points, lines, circle edge points, 3-D points and surface normals
/// in one adjustment, residuals weighted by their a-priori sigma converted to object space at the
/// point's depth, a 6x6 covariance as accuracy estimate, and outlier detection that removes the
/// observation with the largest normalised residual and solves again until no gross error is
/// left. Buffers grow only when more observations arrive than ever before (reserve() up front to
/// keep solve() allocation-free).
class PoseSolver {
 public:
  explicit PoseSolver(const PoseSolverParams& params = {}) : p_(params) {}
  /// Grow the work buffers for up to this many observations of each type.
  void reserve(std::size_t points, std::size_t lines, std::size_t circles = 0, std::size_t points3d = 0,
               std::size_t normals = 0);
  PoseSolverParams& params() { return p_; }

  /// Solve from `T_init` with every type of observation in one adjustment. Flags (see
  /// InlierFlags) receive 1 for kept and 0 for rejected observations. Invalid observations
  /// (non-finite values, sigma <= 0, two coincident line points, zero normals, radius <= 0) are
  /// rejected up front and flagged 0. Status: kTooFewObservations below min_observations valid
  /// observations or 6 scalar residuals, kDegenerate for a rank-deficient normal matrix (e.g.
  /// all points identical, a single circle: rotation about its axis, normals only: translation)
  /// or focal_px <= 0, kDiverged for a non-finite T_init or step or a final pose with observed
  /// 2-D points or line points at or behind the camera. On failure T_cam_obj is T_init and the
  /// covariance zero. Circle edge points and normals that are unusable at the final pose (see
  /// CircleObservation, normalised_normal_residual) are flagged 0.
  ///
  /// Flow: optional robust pass (see PoseSolverParams::robust_init), then plain weighted least
  /// squares removing the active observation with the largest standardised residual (residual
  /// over its own standard deviation, I - J H^-1 J^T; for observations with m scalar residuals
  /// the chi-square value r^T Q^-1 r mapped to the common scale, see PoseSolverParams) while it
  /// exceeds the threshold; once, rejected observations whose prediction error is within the
  /// threshold are re-admitted and the loop repeats. Gauss-Newton steps that would increase
  /// their objective are halved (up to 10 times).
  ///
  /// Convergence basin: points, lines and 3-D points converge from several centimetres and tens
  /// of degrees; a circle edge point is described well only while the pose error moves the
  /// circle by clearly less than its radius (with circles alone, start within a few mm).
  PoseResult solve(const geometry::SE3& T_init, const ObservationSet& obs, const InlierFlags& flags = {});

  /// 2-D points and lines only (the original interface); same as solve(T_init, {points, lines},
  /// {point_inlier, line_inlier}).
  PoseResult solve(const geometry::SE3& T_init, std::span<const PointObservation> points,
                   std::span<const LineObservation> lines, std::span<std::uint8_t> point_inlier = {},
                   std::span<std::uint8_t> line_inlier = {});

 private:
  /// Sums of one linearisation in normalised (sigma) units: H = sum rho J^T J, g = sum rho J^T r.
  struct NormalEquations {
    geometry::Matrix6d H = geometry::Matrix6d::Zero();
    geometry::Vector6d g = geometry::Vector6d::Zero();
    double chi2 = 0.0;      ///< sum of squared normalised residuals (unweighted by rho)
    double weighted_chi2 = 0.0;  ///< sum of rho times squared normalised residuals
    /// weighted_chi2 with the point and line weights of the reference linearisation (depths in
    /// depth_ref_): the objective the step from there minimised.
    double frozen_chi2 = 0.0;
    double sum_sq_px = 0.0; ///< sum of squared image residuals converted to pixels
    int residuals = 0;      ///< scalar residuals accumulated
    int image_residuals = 0;  ///< of which from 2-D points, lines and circles
    int behind = 0;         ///< active 2-D points / line points at or behind the camera
    int unusable = 0;       ///< active circle points / normals that cannot be evaluated at this pose
  };
  /// One evaluated observation: m scalar residuals (rows beyond m are zero).
  struct Eval {
    Eigen::Vector3d rw = Eigen::Vector3d::Zero();  ///< normalised residuals
    Eigen::Matrix<double, 3, 6> Jw;                ///< normalised Jacobian (when requested)
    int m = 0;               ///< scalar residuals (0: unusable at this pose)
    Eigen::Vector2d depth = Eigen::Vector2d::Ones();  ///< depths (m, clamped) behind the weights of points / lines
  };
  enum class Kind : std::uint8_t { kPoint, kLine, kCircle, kPoint3, kNormal };
  /// One camera at the current pose T of the solve: T_c = T_cam_ref * T, and the Jacobian of a
  /// left update of T in camera coordinates, Ad(T_cam_ref) (applied only when `moved`).
  struct CameraPose {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    geometry::Matrix6d Ad = geometry::Matrix6d::Identity();
    ResidualWeighting w;
  };
  /// Fills cams_ for the pose T (and the set's cameras).
  void pose_cameras(const geometry::SE3& T, const ObservationSet& obs);
  enum class Statistic : std::uint8_t { kPlain, kStandardised };

  void prepare(const ObservationSet& obs);
  void locate(std::size_t slot, Kind& kind, std::size_t& index) const;
  /// Residuals (and Jacobian) of one slot at the pose of the last pose_cameras() call.
  void evaluate(const ObservationSet& obs, std::size_t slot, bool jacobian, Eval& e) const;
  NormalEquations linearise(const geometry::SE3& T, const ObservationSet& obs, bool robust);
  SolveStatus gauss_newton(geometry::SE3& T, const ObservationSet& obs, bool robust, int max_iterations,
                           int& iterations, bool& converged, NormalEquations& last);
  void update_robust_weights(double scale);
  /// Per-observation chi2_ / dims_; returns the rho-weighted frozen-weight objective (kPlain).
  double statistics(const geometry::SE3& T, const geometry::Matrix6d& H_inv, const ObservationSet& obs,
                    Statistic kind);
  double stat(std::size_t slot, double scale) const;
  double quantile_scale();
  int count_active() const;
  int min_active() const;  ///< fewest active observations a solve needs (1 with a prior)

  PoseSolverParams p_;
  // Per observation "slot": points, then lines, circles, 3-D points, normals.
  std::size_t end_points_ = 0, end_lines_ = 0, end_circles_ = 0, end_points3d_ = 0, end_normals_ = 0;
  std::vector<std::uint8_t> active_;  ///< 1 active, 0 rejected, 2 invalid input
  std::vector<std::uint8_t> dims_;    ///< scalar residuals of the slot's last statistic (0: unusable)
  std::vector<double> rho_;           ///< IRLS weights
  std::vector<double> chi2_;          ///< per-slot quadratic form of the last statistic (units of sigma^2)
  std::vector<double> scratch_;       ///< quantile work buffer
  /// Depths behind the point / line weights of the last accepted linearisation, and of the latest
  /// (trial) one; Gauss-Newton steps are accepted on the objective with the weights frozen.
  std::vector<Eigen::Vector2d> depth_ref_, depth_trial_;
  // Per-type caches.
  std::vector<RayBasis> point_bases_;
  std::vector<Eigen::Vector3d> line_normals_;
  std::vector<Eigen::Vector3d> circle_axes_;      ///< unit circle axes, object frame
  std::vector<DirectionBasis> normal_bases_;      ///< around the measured normals, camera frame
  std::vector<Eigen::Vector3d> normal_objs_;      ///< unit model normals, object frame
  std::array<CameraPose, kMaxSolveCameras> cams_;  ///< at the pose of the last pose_cameras()
  bool multi_camera_ = false;                     ///< the current solve has ObservationSet::cameras
  bool has_prior_ = false;                        ///< the current solve has a valid prior
  geometry::SE3 prior_T_;                         ///< its pose
  geometry::Matrix6d prior_U_ = geometry::Matrix6d::Zero();  ///< upper Cholesky factor of its information
};

}  // namespace v4r::estimation
