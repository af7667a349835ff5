// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cmath>

#include "v4r/geometry/se3.hpp"

namespace v4r::geometry {

/// \brief SE(3) adjoint in (v, w) order with left updates: T * exp(d) * T^-1 == exp(Ad(T) * d);
/// Ad(T) = [R, hat(t) R; 0, R]. Maps a left-tangent covariance between frames:
/// cov_a = Ad(T_a_b) cov_b Ad(T_a_b)^T.
inline Matrix6d adjoint(const SE3& T) {
  const Eigen::Matrix3d R = T.rotation();
  Matrix6d A = Matrix6d::Zero();
  A.topLeftCorner<3, 3>() = R;
  A.topRightCorner<3, 3>() = hat(T.translation()) * R;
  A.bottomRightCorner<3, 3>() = R;
  return A;
}

/// \brief SE(3) left Jacobian in (v, w) order: exp(xi + d) ~= exp(J_l(xi) * d) * exp(xi) for
/// small d. J_l(xi) = [J, Q; 0, J] with J the SO(3) left Jacobian of w and Q the coupling block
/// of v and w (series expansions for small |w|). J_l(0) = I.
inline Matrix6d left_jacobian(const Vector6d& xi) {
  const Eigen::Vector3d v = xi.head<3>();
  const Eigen::Vector3d w = xi.tail<3>();
  const double th2 = w.squaredNorm();
  const Eigen::Matrix3d W = hat(w), V = hat(v);
  const Eigen::Matrix3d WW = W * W;
  // Coefficients of J = I + a W + b W^2 and of the coupling block Q (series below 0.1 rad,
  // where the closed forms lose digits to cancellation).
  double a, b, c1, c2, c3;
  if (th2 < 1e-2) {
    const double th4 = th2 * th2;
    a = 0.5 - th2 / 24.0 + th4 / 720.0;
    b = 1.0 / 6.0 - th2 / 120.0 + th4 / 5040.0;
    c1 = b;
    c2 = 1.0 / 24.0 - th2 / 720.0 + th4 / 40320.0;
    c3 = 1.0 / 120.0 - th2 / 2520.0 + th4 / 120960.0;
  } else {
    const double th = std::sqrt(th2), s = std::sin(th), c = std::cos(th);
    a = (1.0 - c) / th2;
    b = (th - s) / (th2 * th);
    c1 = b;
    c2 = (th2 + 2.0 * c - 2.0) / (2.0 * th2 * th2);
    c3 = (2.0 * th - 3.0 * s + th * c) / (2.0 * th2 * th2 * th);
  }
  const Eigen::Matrix3d J = Eigen::Matrix3d::Identity() + a * W + b * WW;
  const Eigen::Matrix3d WVW = W * V * W;
  const Eigen::Matrix3d Q = 0.5 * V + c1 * (W * V + V * W + WVW) + c2 * (WW * V + V * WW - 3.0 * WVW) +
                            c3 * (WVW * W + W * WVW);
  Matrix6d Jl = Matrix6d::Zero();
  Jl.topLeftCorner<3, 3>() = J;
  Jl.topRightCorner<3, 3>() = Q;
  Jl.bottomRightCorner<3, 3>() = J;
  return Jl;
}

/// \brief Covariance of (translation, rotation) of a pose T from the covariance of its left
/// tangent (v, w) (T_true = exp(xi) T): to first order the translation error is v + w x t and the
/// rotation error w (a small rotation applied on the left, in the frame T maps into). This is the
/// convention of `sigma_tx..sigma_rz` in poses.csv, of `ObjectPose cov=` and of ROS's
/// PoseWithCovariance (x, y, z, rotation about x, y, z).
inline Matrix6d translation_rotation_covariance(const SE3& T, const Matrix6d& cov_left) {
  Matrix6d J = Matrix6d::Identity();
  J.topRightCorner<3, 3>() = -hat(T.translation());
  return J * cov_left * J.transpose();
}

/// \brief How far a camera-frame point's pinhole projection (fx, fy; no distortion) moves along
/// the unit image direction n under a left pose update (v, w), Xc' = exp((v, w)) Xc, to first
/// order: the row d(n . project(Xc)) / d(v, w) = [nJ, Xc x nJ], with nJ = n' d(project)/d(Xc).
/// The Jacobian of a point-to-edge distance measured along the edge's normal. Xc.z() > 0.
inline Vector6d normal_motion_jacobian(const Eigen::Vector3d& Xc, const Eigen::Vector2d& n, double fx, double fy) {
  const double iz = 1.0 / Xc.z();
  const Eigen::Vector3d nJ(n.x() * fx * iz, n.y() * fy * iz, -(n.x() * fx * Xc.x() + n.y() * fy * Xc.y()) * iz * iz);
  Vector6d J;
  J.head<3>() = nJ;
  J.tail<3>() = Xc.cross(nJ);
  return J;
}

}  // namespace v4r::geometry
