// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace v4r::geometry {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// Skew-symmetric matrix: hat(w) * x == w.cross(x).
inline Eigen::Matrix3d hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d m;
  m << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return m;
}

/// \brief SO(3) exponential of a rotation vector (axis * angle, radians): exp(hat(w)).
/// Identity: so3_log(so3_exp(w)) == w for |w| < pi.
inline Eigen::Matrix3d so3_exp(const Eigen::Vector3d& w) {
  const double th2 = w.squaredNorm();
  const Eigen::Matrix3d W = hat(w);
  double a, b;
  if (th2 < 1e-12) {
    a = 1.0 - th2 / 6.0;
    b = 0.5 - th2 / 24.0;
  } else {
    const double th = std::sqrt(th2);
    a = std::sin(th) / th;
    b = (1.0 - std::cos(th)) / th2;
  }
  return Eigen::Matrix3d::Identity() + a * W + b * W * W;
}

/// \brief Rotation vector (OpenCV Rodrigues convention) of a rotation matrix.
inline Eigen::Vector3d so3_log(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  Eigen::Vector3d w = aa.axis() * aa.angle();
  if (!w.allFinite()) w.setZero();
  return w;
}

/// \brief A rigid transform T_a_b in SE(3): maps coordinates of frame b into frame a,
/// p_a = T_a_b * p_b = R * p_b + t. Composition cancels subscripts: T_a_c = T_a_b * T_b_c.
///
/// Tangent vectors are ordered (v, w): translation part first, rotation part second, and
/// updates are applied on the left: T <- exp(delta) * T.
class SE3 {
 public:
  SE3() : q_(Eigen::Quaterniond::Identity()), t_(Eigen::Vector3d::Zero()) {}
  SE3(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) : q_(q.normalized()), t_(t) {}
  SE3(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) : q_(Eigen::Quaterniond(R).normalized()), t_(t) {}

  /// From translation (metres) and rotation vector (radians, OpenCV Rodrigues).
  static SE3 from_rvec(const Eigen::Vector3d& t, const Eigen::Vector3d& rvec) {
    return SE3(Eigen::Matrix3d(so3_exp(rvec)), t);
  }

  /// exp of a twist xi = (v, w). Identity: SE3::exp(T.log()) == T.
  static SE3 exp(const Vector6d& xi) {
    const Eigen::Vector3d v = xi.head<3>();
    const Eigen::Vector3d w = xi.tail<3>();
    const double th2 = w.squaredNorm();
    const Eigen::Matrix3d W = hat(w);
    double b, c;
    if (th2 < 1e-12) {
      b = 0.5 - th2 / 24.0;
      c = 1.0 / 6.0 - th2 / 120.0;
    } else {
      const double th = std::sqrt(th2);
      const double sh = std::sin(0.5 * th);
      b = 2.0 * sh * sh / th2;  // (1 - cos th) / th^2 without cancellation
      c = (th - std::sin(th)) / (th2 * th);
    }
    const Eigen::Matrix3d V = Eigen::Matrix3d::Identity() + b * W + c * W * W;
    return SE3(Eigen::Matrix3d(so3_exp(w)), V * v);
  }

  /// log: the twist xi with exp(xi) == *this.
  [[nodiscard]] Vector6d log() const {
    const Eigen::Vector3d w = so3_log(rotation());
    const double th2 = w.squaredNorm();
    const Eigen::Matrix3d W = hat(w);
    Eigen::Matrix3d Vinv;
    if (th2 < 1e-8) {
      Vinv = Eigen::Matrix3d::Identity() - 0.5 * W + W * W / 12.0;
    } else {
      const double th = std::sqrt(th2);
      // (1 - th sin th / (2 (1 - cos th))) / th^2, written without the cancellation of 1 - cos.
      const double k = (1.0 - 0.5 * th / std::tan(0.5 * th)) / th2;
      Vinv = Eigen::Matrix3d::Identity() - 0.5 * W + k * W * W;
    }
    Vector6d xi;
    xi.head<3>() = Vinv * t_;
    xi.tail<3>() = w;
    return xi;
  }

  [[nodiscard]] SE3 inverse() const {
    const Eigen::Quaterniond qi = q_.conjugate();
    return SE3(qi, -(qi * t_));
  }
  SE3 operator*(const SE3& o) const { return SE3(q_ * o.q_, q_ * o.t_ + t_); }
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q_ * p + t_; }

  [[nodiscard]] Eigen::Matrix3d rotation() const { return q_.toRotationMatrix(); }
  [[nodiscard]] const Eigen::Quaterniond& quaternion() const { return q_; }
  [[nodiscard]] const Eigen::Vector3d& translation() const { return t_; }
  [[nodiscard]] Eigen::Vector3d rvec() const { return so3_log(rotation()); }
  [[nodiscard]] Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.topLeftCorner<3, 3>() = rotation();
    m.topRightCorner<3, 1>() = t_;
    return m;
  }
  void set_translation(const Eigen::Vector3d& t) { t_ = t; }

 private:
  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
};

/// Angle (radians) of the relative rotation between two poses.
inline double rotation_angle_between(const SE3& a, const SE3& b) {
  return a.quaternion().angularDistance(b.quaternion());
}

}  // namespace v4r::geometry
