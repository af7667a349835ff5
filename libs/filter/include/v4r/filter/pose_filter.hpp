// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <limits>

#include <Eigen/Core>

#include "v4r/geometry/se3.hpp"
#include "v4r/geometry/se3_jacobians.hpp"

namespace v4r::filter {

using Matrix12d = Eigen::Matrix<double, 12, 12>;
using Vector12d = Eigen::Matrix<double, 12, 1>;

/// \brief Settings of PoseFilter. Process model: white acceleration noise of a continuous-time
/// constant-velocity model (consistent for any sequence of time steps: two predictions by dt/2
/// equal one by dt), acting on the object: linear acceleration of the object origin and angular
/// acceleration about it (mapped into the left twist, where a change of the angular velocity
/// also changes v by its lever arm). Its spectral densities are accel_noise^2 * reference_dt
/// (m^2/s^3) and angular_accel_noise^2 * reference_dt (rad^2/s^3), so that over one step of
/// reference_dt the velocity changes with standard deviation accel_noise * reference_dt, as if
/// the acceleration had standard deviation accel_noise during that frame. Use about the largest
/// acceleration the object undergoes.
struct PoseFilterParams {
  double accel_noise = 2.0;                  ///< m/s^2, translation (per frame of reference_dt)
  double angular_accel_noise = 4.0;          ///< rad/s^2, rotation (per frame of reference_dt)
  double init_velocity_sigma = 0.5;          ///< m/s, velocity uncertainty after reset()
  double init_angular_velocity_sigma = 1.0;  ///< rad/s, angular velocity uncertainty after reset()
  double reference_dt = 1.0 / 30.0;          ///< s, frame interval at which the noise levels hold
  /// Adaptive process noise: while the measurements agree with the prediction (innovation chi^2
  /// <= motion_chi2) the noise is scaled down by noise_decay per update, to min_noise_scale (an
  /// object at rest is reported at rest); a measurement beyond motion_chi2 restores full noise at
  /// once, for that very update (no lag behind a real motion).
  bool adapt_noise = false;
  double min_noise_scale = 1e-7;  ///< smallest scale of the process noise
  double noise_decay = 0.5;       ///< per consistent update
  double motion_chi2 = 10.0;      ///< chi^2 (6 dof) above which a measurement shows motion (about 88 %)
};

/// \brief Extended Kalman filter on SE(3) with a constant-velocity motion model (paper section 6:
/// "an extended Kalman filter ... smoothes the signal").
///
/// State: the pose T (T_cam_obj or T_ref_obj) and a twist velocity vel = (v, w) in the same
/// left-tangent convention as SE3, so that T(t + dt) = exp(vel * dt) * T(t) (m/s, rad/s; the
/// screw motion is fixed in the left frame). Error state (12): the pose error xi with
/// T_true = exp(xi) * T and the velocity error vel_true - vel; covariance 12 x 12 (m, rad, m/s,
/// rad/s). Pure functions of dt: no clock inside, no allocation, never throws. Invalid inputs
/// (negative or non-finite dt, non-finite poses or covariances, a non-positive-definite
/// innovation covariance) leave the state unchanged.
class PoseFilter {
 public:
  /// Returned by update() / innovation_chi2() for a measurement that cannot be used.
  static constexpr double kInvalidChi2 = std::numeric_limits<double>::infinity();

  explicit PoseFilter(const PoseFilterParams& p = {});

  /// Start from pose T with covariance pose_cov (left tangent, m^2 / rad^2), zero velocity with
  /// the params' initial velocity sigmas, no correlation. Non-finite input: the filter becomes
  /// uninitialised.
  void reset(const geometry::SE3& T, const geometry::Matrix6d& pose_cov);
  /// Forget the velocity (zero, initial sigmas, no correlation with the pose), keep the pose.
  void reset_velocity();
  [[nodiscard]] bool initialised() const { return initialised_; }

  /// Pose dt seconds ahead, exp(vel * dt) * T, without changing the state (for placing search
  /// windows). Returns pose() for an invalid dt.
  [[nodiscard]] geometry::SE3 predict_pose(double dt) const;
  /// Time update by dt seconds (dt >= 0; dt = 0 leaves the state unchanged). P <- F P F^T + Q.
  void predict(double dt);

  /// Normalised innovation squared of a measured pose with covariance cov (left tangent: the
  /// measurement is exp(n) * T_true, n ~ N(0, cov)): y^T S^-1 y, y = log(T_meas * T^-1),
  /// S = P_pose + cov; chi-square with 6 dof for a consistent measurement. kInvalidChi2 for
  /// invalid input or before initialisation.
  [[nodiscard]] double innovation_chi2(const geometry::SE3& T_meas, const geometry::Matrix6d& cov) const;
  /// Measurement update with a measured pose and its 6x6 covariance (left tangent). Returns the
  /// normalised innovation squared (see innovation_chi2) so callers can gate outliers; the
  /// update is applied only when it is finite and <= gate_chi2 (default: always). Before
  /// initialisation the filter is reset to the measurement and 0 is returned.
  double update(const geometry::SE3& T_meas, const geometry::Matrix6d& cov,
                double gate_chi2 = std::numeric_limits<double>::infinity());

  [[nodiscard]] const geometry::SE3& pose() const { return T_; }
  [[nodiscard]] geometry::Vector6d velocity() const { return vel_; }
  [[nodiscard]] Matrix12d covariance() const { return P_; }
  [[nodiscard]] geometry::Matrix6d pose_covariance() const { return P_.topLeftCorner<6, 6>(); }
  [[nodiscard]] const PoseFilterParams& params() const { return p_; }
  /// Significance of the velocity estimate: vel^T P_vel^-1 vel (chi-square with 6 dof for an
  /// object at rest); kInvalidChi2 before initialisation or for a singular velocity covariance.
  [[nodiscard]] double velocity_chi2() const;
  /// At rest (another filter's velocity test says so): the velocity is zero, known to within
  /// velocity_sigma (m/s) and angular_velocity_sigma (rad/s), uncorrelated with the pose; the
  /// pose is then an average of the measurements, not the end of a fitted line.
  void hold_still(double velocity_sigma, double angular_velocity_sigma);
  /// Current scale of the process noise (1 without adaptation).
  [[nodiscard]] double noise_scale() const { return p_.adapt_noise ? noise_scale_ : 1.0; }
  void set_params(const PoseFilterParams& p) { p_ = p; }

  /// Error-state transition of a time update by dt with velocity vel:
  /// F = [Ad(exp(vel dt)), dt * J_l(vel dt); 0, I] (first order in the error state).
  static Matrix12d transition_jacobian(const geometry::Vector6d& vel, double dt);
  /// Process noise of a time update by dt from the current pose: per object-centred axis with
  /// density q (see PoseFilterParams), [q dt^3 / 3, q dt^2 / 2; q dt^2 / 2, q dt] on (pose,
  /// velocity), mapped to the left tangent with B = [I, hat(t); 0, I] (t: object origin in the
  /// left frame; an object-centred perturbation (dc, dtheta) is the left perturbation
  /// (dc + hat(t) dtheta, dtheta)).
  [[nodiscard]] Matrix12d process_noise(double dt) const;

 private:
  /// Zero velocity with the given sigmas, uncorrelated with the pose.
  void zero_velocity(double velocity_sigma, double angular_velocity_sigma);

  PoseFilterParams p_;
  geometry::SE3 T_;
  geometry::Vector6d vel_ = geometry::Vector6d::Zero();
  Matrix12d P_ = Matrix12d::Zero();
  Matrix12d last_q_ = Matrix12d::Zero();  // process noise the last time update left out (adaptation)
  double noise_scale_ = 1.0;
  bool initialised_ = false;
};

}  // namespace v4r::filter
