// v4r - robust model-based object tracking. MIT licence.
//
// Error-state EKF on SE(3). Prediction: T <- exp(vel dt) T, vel <- vel; the pose error
// xi (T_true = exp(xi) T) propagates as xi' = Ad(exp(vel dt)) xi + dt J_l(vel dt) dvel, because
// exp((vel + dvel) dt) ~= exp(J_l(vel dt) dvel dt) exp(vel dt) and
// exp(a) exp(xi) exp(-a) = exp(Ad(exp(a)) xi). Update: innovation y = log(T_meas T^-1) ~= xi + n
// (H = [I 0]), Joseph-form covariance update, then the correction dxi = K y is applied on the
// left and the covariance is carried over to the new linearisation point:
// exp(dxi + e) ~= exp(J_l(dxi) e) exp(dxi), so P_pose <- J_l(dxi) P J_l(dxi)^T (with cross terms).

#include "v4r/filter/pose_filter.hpp"

#include <cmath>

#include <Eigen/Cholesky>

namespace v4r::filter {

namespace {

using geometry::hat;
using geometry::Matrix6d;
using geometry::SE3;
using geometry::Vector6d;

bool finite(const SE3& T) { return T.translation().allFinite() && T.quaternion().coeffs().allFinite(); }

void symmetrise(Matrix12d& P) { P = 0.5 * (P + P.transpose()).eval(); }

}  // namespace

PoseFilter::PoseFilter(const PoseFilterParams& p) : p_(p) {}

void PoseFilter::reset(const SE3& T, const Matrix6d& pose_cov) {
  if (!finite(T) || !pose_cov.allFinite()) {
    initialised_ = false;
    return;
  }
  T_ = T;
  P_.setZero();
  P_.topLeftCorner<6, 6>() = 0.5 * (pose_cov + pose_cov.transpose());
  initialised_ = true;
  reset_velocity();
  last_q_.setZero();
}

void PoseFilter::zero_velocity(double velocity_sigma, double angular_velocity_sigma) {
  vel_.setZero();
  P_.topRightCorner<6, 6>().setZero();
  P_.bottomLeftCorner<6, 6>().setZero();
  P_.bottomRightCorner<6, 6>().setZero();
  for (int i = 0; i < 3; ++i) {
    P_(6 + i, 6 + i) = velocity_sigma * velocity_sigma;
    P_(9 + i, 9 + i) = angular_velocity_sigma * angular_velocity_sigma;
  }
}

void PoseFilter::reset_velocity() {
  zero_velocity(p_.init_velocity_sigma, p_.init_angular_velocity_sigma);
  noise_scale_ = 1.0;
}

SE3 PoseFilter::predict_pose(double dt) const {
  if (!(dt > 0.0) || !std::isfinite(dt)) return T_;
  return SE3::exp(vel_ * dt) * T_;
}

Matrix12d PoseFilter::transition_jacobian(const Vector6d& vel, double dt) {
  const Vector6d step = vel * dt;
  Matrix12d F = Matrix12d::Identity();
  F.topLeftCorner<6, 6>() = geometry::adjoint(SE3::exp(step));
  F.topRightCorner<6, 6>() = dt * geometry::left_jacobian(step);
  return F;
}

Matrix12d PoseFilter::process_noise(double dt) const {
  // Object-centred per-axis constant-velocity noise ...
  Matrix12d Q = Matrix12d::Zero();
  const double dt2 = dt * dt, dt3 = dt2 * dt;
  for (int i = 0; i < 6; ++i) {
    const double sigma = i < 3 ? p_.accel_noise : p_.angular_accel_noise;
    const double q = sigma * sigma * p_.reference_dt;
    Q(i, i) = q * dt3 / 3.0;
    Q(i, 6 + i) = Q(6 + i, i) = q * dt2 / 2.0;
    Q(6 + i, 6 + i) = q * dt;
  }
  // ... mapped to the left tangent: B Q B^T with B = diag(Bt, Bt), Bt = [I, hat(t); 0, I].
  Matrix12d B = Matrix12d::Identity();
  const Eigen::Matrix3d H = hat(T_.translation());
  B.block<3, 3>(0, 3) = H;
  B.block<3, 3>(6, 9) = H;
  return B * Q * B.transpose();
}

void PoseFilter::predict(double dt) {
  if (!initialised_ || !(dt > 0.0) || !std::isfinite(dt)) return;
  const Matrix12d F = transition_jacobian(vel_, dt);
  const Matrix12d Q = process_noise(dt);
  const double scale = p_.adapt_noise ? noise_scale_ : 1.0;
  const Matrix12d P = F * P_ * F.transpose() + scale * Q;
  const SE3 T = SE3::exp(vel_ * dt) * T_;
  if (!P.allFinite() || !finite(T)) return;
  T_ = T;
  P_ = P;
  last_q_ = (1.0 - scale) * Q;  // what a full-scale time update would have added on top
  symmetrise(P_);
}

double PoseFilter::velocity_chi2() const {
  if (!initialised_) return kInvalidChi2;
  const Eigen::LLT<Matrix6d> llt(P_.bottomRightCorner<6, 6>());
  if (llt.info() != Eigen::Success) return kInvalidChi2;
  const double chi2 = vel_.dot(llt.solve(vel_));
  return std::isfinite(chi2) && chi2 >= 0.0 ? chi2 : kInvalidChi2;
}

void PoseFilter::hold_still(double velocity_sigma, double angular_velocity_sigma) {
  if (!initialised_ || !std::isfinite(velocity_sigma) || !std::isfinite(angular_velocity_sigma)) return;
  zero_velocity(velocity_sigma, angular_velocity_sigma);
}

double PoseFilter::innovation_chi2(const SE3& T_meas, const Matrix6d& cov) const {
  if (!initialised_ || !finite(T_meas) || !cov.allFinite()) return kInvalidChi2;
  const Vector6d y = (T_meas * T_.inverse()).log();
  const Matrix6d S = P_.topLeftCorner<6, 6>() + 0.5 * (cov + cov.transpose());
  const Eigen::LLT<Matrix6d> llt(S);
  if (llt.info() != Eigen::Success || !y.allFinite()) return kInvalidChi2;
  const double chi2 = y.dot(llt.solve(y));
  return std::isfinite(chi2) && chi2 >= 0.0 ? chi2 : kInvalidChi2;
}

double PoseFilter::update(const SE3& T_meas, const Matrix6d& cov, double gate_chi2) {
  if (!finite(T_meas) || !cov.allFinite()) return kInvalidChi2;
  if (!initialised_) {
    reset(T_meas, cov);
    return 0.0;
  }
  const Vector6d y = (T_meas * T_.inverse()).log();
  const Matrix6d R = 0.5 * (cov + cov.transpose());
  Eigen::LLT<Matrix6d> llt(P_.topLeftCorner<6, 6>() + R);
  if (llt.info() != Eigen::Success || !y.allFinite()) return kInvalidChi2;
  double chi2 = y.dot(llt.solve(y));
  if (!std::isfinite(chi2) || chi2 < 0.0) return kInvalidChi2;
  if (!(chi2 <= gate_chi2)) return chi2;
  // Adaptive process noise: a measurement the reduced noise cannot explain means the object
  // moves: the time update is redone at full noise (no lag), and the noise stays up.
  bool boosted = false;
  if (p_.adapt_noise && chi2 > p_.motion_chi2 && noise_scale_ < 1.0) {
    const Matrix12d P_full = P_ + last_q_;
    const Eigen::LLT<Matrix6d> llt_full(P_full.topLeftCorner<6, 6>() + R);
    if (llt_full.info() == Eigen::Success) {
      P_ = P_full;
      llt = llt_full;
      chi2 = y.dot(llt.solve(y));
      noise_scale_ = 1.0;
      last_q_.setZero();
      boosted = true;
    }
  }
  if (p_.adapt_noise && !boosted && chi2 <= p_.motion_chi2)
    noise_scale_ = std::max(std::clamp(p_.min_noise_scale, 0.0, 1.0), noise_scale_ * std::clamp(p_.noise_decay, 0.0, 1.0));

  // K = P H^T S^-1 with H = [I 0]: P H^T = P.leftCols<6>().
  const Eigen::Matrix<double, 12, 6> PHt = P_.leftCols<6>();
  const Eigen::Matrix<double, 12, 6> K = llt.solve(PHt.transpose()).transpose();
  const Vector12d dx = K * y;
  Matrix12d IKH = Matrix12d::Identity();
  IKH.leftCols<6>() -= K;
  Matrix12d P = IKH * P_ * IKH.transpose() + K * R * K.transpose();
  // Carry the covariance over to the corrected pose (see the file comment).
  Matrix12d G = Matrix12d::Identity();
  G.topLeftCorner<6, 6>() = geometry::left_jacobian(dx.head<6>());
  P = G * P * G.transpose();
  const SE3 T = SE3::exp(dx.head<6>()) * T_;
  if (!P.allFinite() || !dx.allFinite() || !finite(T)) return kInvalidChi2;
  T_ = T;
  vel_ += dx.tail<6>();
  P_ = P;
  symmetrise(P_);
  return chi2;
}

}  // namespace v4r::filter
