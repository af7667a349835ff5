// v4r - robust model-based object tracking. MIT licence.
#pragma once

// \brief Object-space residuals of the Wunsch pose solver (paper section 5) with analytic
// Jacobians. Residuals are 3-D discrepancies in metres measured in the camera frame (2-D points,
// lines, circle edge points, 3-D points), or, for surface normals, directions in radians.
//
// Jacobians are with respect to a left update of the pose, T <- exp(delta) * T with
// delta = (v, w) in R^6 (metres, radians). For p = T * X (camera frame) and a small delta,
// exp(delta) * p ~= p + v + w x p, so dp/ddelta = [I3, -hat(p)], and for any fixed direction a,
// d(a . p)/ddelta = [a^T, (p x a)^T].

#include <algorithm>
#include <cmath>

#include <Eigen/Core>

#include "v4r/geometry/se3.hpp"

namespace v4r::estimation {

using Matrix26d = Eigen::Matrix<double, 2, 6>;
using Matrix16d = Eigen::Matrix<double, 1, 6>;
using Matrix36d = Eigen::Matrix<double, 3, 6>;

/// \brief Orthonormal basis (e1, e2) of the plane perpendicular to the line of sight u of an
/// image point; e1 has no optical-axis component (tangential), e2 = u x e1 (radial-ish).
///
/// A normalised image displacement d = (dx, dy) at depth z moves the camera-frame point by
/// z * (dx, dy, 0), whose components are z * (e1 . (d, 0)) with unit gain and
/// z * (e2 . (d, 0)) with gain cos_theta = u.z (the ray's angle to the optical axis):
/// isotropic image noise sigma maps to sigmas (z * sigma, z * sigma * cos_theta).
struct RayBasis {
  Eigen::Vector3d u = Eigen::Vector3d::UnitZ();   ///< unit line of sight, camera frame
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitX();  ///< unit, perpendicular to u and to the optical axis
  Eigen::Vector3d e2 = Eigen::Vector3d::UnitY();  ///< unit, e2 = u x e1
  double cos_theta = 1.0;                         ///< u.z, cosine of the ray's off-axis angle
};

/// Basis of the line of sight through the normalised image point xn = (x/z, y/z).
/// Identity: e1 . u == e2 . u == e1 . e2 == 0, |e1| == |e2| == 1.
inline RayBasis ray_basis(const Eigen::Vector2d& xn) {
  RayBasis b;
  b.u = Eigen::Vector3d(xn.x(), xn.y(), 1.0).normalized();
  const double s = std::hypot(b.u.x(), b.u.y());
  if (s > 1e-12) {
    b.e1 = Eigen::Vector3d(-b.u.y() / s, b.u.x() / s, 0.0);
  } else {
    b.e1 = Eigen::Vector3d::UnitX();
  }
  b.e2 = b.u.cross(b.e1);
  b.cos_theta = b.u.z();
  return b;
}

/// Unit normal of the interpretation plane through the camera centre and the image line through
/// the normalised points xn1, xn2: n = normalize((xn1, 1) x (xn2, 1)). Returns zero when the two
/// points (nearly) coincide. Identity: n . (xn1, 1) == n . (xn2, 1) == 0.
inline Eigen::Vector3d interpretation_plane_normal(const Eigen::Vector2d& xn1, const Eigen::Vector2d& xn2) {
  const Eigen::Vector3d n = Eigen::Vector3d(xn1.x(), xn1.y(), 1.0).cross(Eigen::Vector3d(xn2.x(), xn2.y(), 1.0));
  const double len = n.norm();
  if (!(len > 1e-12)) return Eigen::Vector3d::Zero();
  return n / len;
}

/// Point discrepancy at a camera-frame point p: the component of p perpendicular to the line of
/// sight, r = (e1 . p, e2 . p) in metres; |r| is p's distance from the line of sight.
/// J (optional) = d r / d delta = [e^T, (p x e)^T] per row.
inline Eigen::Vector2d point_residual_at(const Eigen::Vector3d& p, const RayBasis& b, Matrix26d* J = nullptr) {
  if (J != nullptr) {
    J->block<1, 3>(0, 0) = b.e1.transpose();
    J->block<1, 3>(0, 3) = p.cross(b.e1).transpose();
    J->block<1, 3>(1, 0) = b.e2.transpose();
    J->block<1, 3>(1, 3) = p.cross(b.e2).transpose();
  }
  return {b.e1.dot(p), b.e2.dot(p)};
}

/// Point discrepancy of model point X_obj (object frame) under pose T_cam_obj; see point_residual_at.
inline Eigen::Vector2d point_residual(const geometry::SE3& T_cam_obj, const Eigen::Vector3d& X_obj, const RayBasis& b,
                                      Matrix26d* J = nullptr) {
  return point_residual_at(T_cam_obj * X_obj, b, J);
}

/// Plane discrepancy at a camera-frame point p: the signed distance r = n . p (metres) of p from
/// the interpretation plane with unit normal n. J (optional) = [n^T, (p x n)^T].
inline double plane_residual_at(const Eigen::Vector3d& p, const Eigen::Vector3d& n, Matrix16d* J = nullptr) {
  if (J != nullptr) {
    J->block<1, 3>(0, 0) = n.transpose();
    J->block<1, 3>(0, 3) = p.cross(n).transpose();
  }
  return n.dot(p);
}

/// Line discrepancy of a model edge (X1_obj, X2_obj) under pose T_cam_obj: the distances of both
/// edge points from the interpretation plane with unit normal n, r = (n . T*X1, n . T*X2) metres.
inline Eigen::Vector2d line_residual(const geometry::SE3& T_cam_obj, const Eigen::Vector3d& X1_obj,
                                     const Eigen::Vector3d& X2_obj, const Eigen::Vector3d& n, Matrix26d* J = nullptr) {
  Matrix16d J1, J2;
  const double r1 = plane_residual_at(T_cam_obj * X1_obj, n, J != nullptr ? &J1 : nullptr);
  const double r2 = plane_residual_at(T_cam_obj * X2_obj, n, J != nullptr ? &J2 : nullptr);
  if (J != nullptr) {
    J->row(0) = J1;
    J->row(1) = J2;
  }
  return {r1, r2};
}

/// \brief How an observation's a-priori image sigma (pixels) becomes object-space sigmas of its
/// discrepancies (Wunsch / paper section 5: sigma_obj = sigma_px * z / focal_px at depth z).
struct ResidualWeighting {
  double focal_px = 500.0;  ///< pixels per normalised unit
  /// First-order exact factors: a point's radial discrepancy (along e2) gets cos(theta), a line's
  /// plane distances get sqrt(1 - n_z^2) (see ImageNoiseMapsToObjectSpaceSigmas). false: 1.
  bool oblique = true;
  double min_depth = 1e-3;  ///< depth (m) used for points at or behind the camera
};

/// Smallest factor sqrt(1 - n_z^2) used in line weights (an image line far outside the image).
inline constexpr double kMinLineGain = 1e-3;

/// Point discrepancy at camera-frame point p divided by its object-space sigmas (units of sigma),
/// Jw (optional) likewise. For an observation displaced by d pixels from the projection of p,
/// |rw| * sigma_px == |d| to first order. Returns true when p is at or behind the camera.
inline bool normalised_point_residual(const Eigen::Vector3d& p, const RayBasis& b, double sigma_px,
                                      const ResidualWeighting& w, Eigen::Vector2d& rw, Matrix26d* Jw = nullptr) {
  const double z = p.z() > w.min_depth ? p.z() : w.min_depth;
  const double i1 = w.focal_px / (sigma_px * z);
  const double i2 = w.oblique ? i1 / b.cos_theta : i1;
  const Eigen::Vector2d r = point_residual_at(p, b, Jw);
  rw = Eigen::Vector2d(r.x() * i1, r.y() * i2);
  if (Jw != nullptr) {
    Jw->row(0) *= i1;
    Jw->row(1) *= i2;
  }
  return !(p.z() > 0.0);
}

/// Line discrepancies of camera-frame edge points p1, p2 divided by their object-space sigmas
/// (units of sigma), Jw (optional) likewise. If the projection of p_k lies d_k pixels from the
/// observed image line, rw_k * sigma_px == +-d_k to first order. Returns true when an edge point
/// is at or behind the camera.
inline bool normalised_line_residual(const Eigen::Vector3d& p1, const Eigen::Vector3d& p2, const Eigen::Vector3d& n,
                                     double sigma_px, const ResidualWeighting& w, Eigen::Vector2d& rw,
                                     Matrix26d* Jw = nullptr) {
  double gain = 1.0;
  if (w.oblique) {
    const double s2 = 1.0 - n.z() * n.z();
    gain = s2 > kMinLineGain * kMinLineGain ? std::sqrt(s2) : kMinLineGain;
  }
  const double base = w.focal_px / (sigma_px * gain);
  const double i1 = base / (p1.z() > w.min_depth ? p1.z() : w.min_depth);
  const double i2 = base / (p2.z() > w.min_depth ? p2.z() : w.min_depth);
  Matrix16d J1, J2;
  const double r1 = plane_residual_at(p1, n, Jw != nullptr ? &J1 : nullptr);
  const double r2 = plane_residual_at(p2, n, Jw != nullptr ? &J2 : nullptr);
  rw = Eigen::Vector2d(r1 * i1, r2 * i2);
  if (Jw != nullptr) {
    Jw->row(0) = J1 * i1;
    Jw->row(1) = J2 * i2;
  }
  return !(p1.z() > 0.0) || !(p2.z() > 0.0);
}

// ---------------------------------------------------------------------------------------------
// 3-D points, surface normals and circles (paper section 5: "2D point, 3D point, 2D line,
// ellipse, surface normal").

/// 3-D point discrepancy at the predicted camera-frame point p = T * X_obj against the measured
/// camera-frame point P (stereo, range sensor): r = p - P, metres. J (optional) = [I3, -hat(p)].
inline Eigen::Vector3d point3_residual_at(const Eigen::Vector3d& p, const Eigen::Vector3d& P, Matrix36d* J = nullptr) {
  if (J != nullptr) {
    J->block<3, 3>(0, 0).setIdentity();
    J->block<3, 3>(0, 3) = -geometry::hat(p);
  }
  return p - P;
}

/// 3-D point discrepancy of model point X_obj under pose T_cam_obj; see point3_residual_at.
inline Eigen::Vector3d point3_residual(const geometry::SE3& T_cam_obj, const Eigen::Vector3d& X_obj,
                                       const Eigen::Vector3d& P_cam, Matrix36d* J = nullptr) {
  return point3_residual_at(T_cam_obj * X_obj, P_cam, J);
}

/// \brief Orthonormal basis (b1, b2) of the plane perpendicular to a unit direction n.
struct DirectionBasis {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();   ///< unit direction
  Eigen::Vector3d b1 = Eigen::Vector3d::UnitX();  ///< unit, perpendicular to n
  Eigen::Vector3d b2 = Eigen::Vector3d::UnitY();  ///< unit, b2 = n x b1
};

/// Basis perpendicular to the direction n (need not be unit; must be non-zero).
/// Identity: b1 . n == b2 . n == b1 . b2 == 0, |b1| == |b2| == |n| == 1.
inline DirectionBasis direction_basis(const Eigen::Vector3d& n) {
  DirectionBasis b;
  b.n = n.normalized();
  // Cross with the coordinate axis least aligned with n: well conditioned for every n.
  Eigen::Index k = 0;
  b.n.cwiseAbs().minCoeff(&k);
  b.b1 = b.n.cross(Eigen::Vector3d::Unit(k)).normalized();
  b.b2 = b.n.cross(b.b1);
  return b;
}

/// Surface-normal discrepancy: the predicted camera-frame normal m = R * n_obj (unit) minus the
/// measured one n_cam, expressed by its two components perpendicular to n_cam:
/// r = (b1 . m, b2 . m), radians for small angles (|r| = sin of the angle between m and n_cam
/// when m . n_cam > 0). Only the rotation enters: J (optional) = [0, (m x b_k)^T] per row.
inline Eigen::Vector2d normal_residual_at(const Eigen::Vector3d& m, const DirectionBasis& b, Matrix26d* J = nullptr) {
  if (J != nullptr) {
    J->block<2, 3>(0, 0).setZero();
    J->block<1, 3>(0, 3) = m.cross(b.b1).transpose();
    J->block<1, 3>(1, 3) = m.cross(b.b2).transpose();
  }
  return {b.b1.dot(m), b.b2.dot(m)};
}

/// Surface-normal discrepancy of the unit object-frame normal n_obj under pose T_cam_obj.
inline Eigen::Vector2d normal_residual(const geometry::SE3& T_cam_obj, const Eigen::Vector3d& n_obj,
                                       const DirectionBasis& b, Matrix26d* J = nullptr) {
  return normal_residual_at(T_cam_obj.quaternion() * n_obj, b, J);
}

/// Below this |cos| of the angle between a line of sight and a circle's plane normal the ray is
/// taken as parallel to the plane (the edge point cannot be back-projected).
inline constexpr double kMinCircleIncidence = 1e-3;

/// \brief Back-projection of one circle edge point onto the circle's plane (camera frame).
struct CircleIntersection {
  double residual = 0.0;  ///< |X - c| - radius, metres (X: the ray's intersection with the plane)
  double depth = 0.0;     ///< z of X, metres (> 0 when valid)
  /// |d r / d xn| / depth: how strongly an image displacement of the edge point (normalised
  /// units) changes the residual, per metre of depth; 1 for a fronto-parallel circle, growing as
  /// the ray meets the plane more obliquely. sigma_r = sigma_px / focal_px * depth * gain.
  double gain = 1.0;
  bool valid = false;  ///< false: ray (nearly) parallel to the plane, X behind the camera or at c
};

/// Circle discrepancy of one edge point: the line of sight d = (xn, 1) through the observed
/// edge point meets the plane of the circle (camera-frame centre c, unit axis a) at
/// X = lambda * d, lambda = (a . c) / (a . d); r = |X - c| - radius. With u = (X - c) / |X - c|
/// and k = (u . d) / (a . d), J (optional) = [k a^T - u^T, k (X x a)^T - (c x u)^T] (derivation:
/// d lambda = (a . dc + da . (c - X)) / (a . d) with dc = v + w x c, da = w x a). The image
/// sensitivity is d r / d xn = lambda * (g_x, g_y), g = u - k a, hence gain = |(g_x, g_y)|.
/// J and the other fields are only meaningful when the result is valid.
inline CircleIntersection circle_residual_at(const Eigen::Vector3d& c, const Eigen::Vector3d& a, double radius,
                                             const Eigen::Vector2d& xn, Matrix16d* J = nullptr) {
  CircleIntersection out;
  const Eigen::Vector3d d(xn.x(), xn.y(), 1.0);
  const double ad = a.dot(d);
  if (!(std::abs(ad) > kMinCircleIncidence * d.norm())) return out;
  const double lambda = a.dot(c) / ad;
  if (!(lambda > 0.0)) return out;
  const Eigen::Vector3d X = lambda * d;
  const Eigen::Vector3d e = X - c;
  const double len = e.norm();
  if (!(len > 1e-12 * (1.0 + c.norm()))) return out;
  const Eigen::Vector3d u = e / len;
  const double k = u.dot(d) / ad;
  if (J != nullptr) {
    J->block<1, 3>(0, 0) = (k * a - u).transpose();
    J->block<1, 3>(0, 3) = (k * X.cross(a) - c.cross(u)).transpose();
  }
  const Eigen::Vector3d g = u - k * a;
  out.residual = len - radius;
  out.depth = lambda;
  out.gain = std::sqrt(g.x() * g.x() + g.y() * g.y());
  out.valid = true;
  return out;
}

/// Circle discrepancy of an edge point xn of the model circle (centre c_obj, axis a_obj unit,
/// radius metres) under pose T_cam_obj; see circle_residual_at.
inline CircleIntersection circle_residual(const geometry::SE3& T_cam_obj, const Eigen::Vector3d& c_obj,
                                          const Eigen::Vector3d& a_obj, double radius, const Eigen::Vector2d& xn,
                                          Matrix16d* J = nullptr) {
  return circle_residual_at(T_cam_obj * c_obj, T_cam_obj.quaternion() * a_obj, radius, xn, J);
}

/// 3-D point discrepancy divided by its isotropic sigma (metres): rw = (p - P) / sigma_m, Jw
/// likewise. Always usable (no line of sight involved).
inline void normalised_point3_residual(const Eigen::Vector3d& p, const Eigen::Vector3d& P, double sigma_m,
                                       Eigen::Vector3d& rw, Matrix36d* Jw = nullptr) {
  const double i = 1.0 / sigma_m;
  rw = point3_residual_at(p, P, Jw) * i;
  if (Jw != nullptr) *Jw *= i;
}

/// Surface-normal discrepancy divided by its sigma (radians per component), Jw likewise. Returns
/// false when the predicted normal m points away from the measured one (m . n < 0): there the
/// two components vanish again at the flipped normal, so the observation is unusable.
inline bool normalised_normal_residual(const Eigen::Vector3d& m, const DirectionBasis& b, double sigma_rad,
                                       Eigen::Vector2d& rw, Matrix26d* Jw = nullptr) {
  const double i = 1.0 / sigma_rad;
  rw = normal_residual_at(m, b, Jw) * i;
  if (Jw != nullptr) *Jw *= i;
  return m.dot(b.n) > 0.0;
}

/// Circle discrepancy divided by its object-space sigma
/// sigma_obj = sigma_px / focal_px * depth * gain (first-order exact for isotropic image noise of
/// sigma_px on the edge point; only the component across the ellipse matters, moving along it
/// keeps X on the circle). gain (see CircleIntersection) is 1 for a fronto-parallel circle and
/// grows like 1 / obliqueness as the plane turns away from the ray: there an image error moves X
/// far along the plane. Without w.oblique gain is taken as 1; it is clamped to kMinLineGain from
/// below and the depth to w.min_depth. If the observed edge point lies d pixels across the
/// ellipse from the image of the circle, |rw| * sigma_px == d to first order. Returns false (rw,
/// Jw unset) when unusable.
///
/// Unlike the point and line weights, which Gauss-Newton freezes within a step (Wunsch), this
/// weight changes strongly with the pose (depth and obliqueness of the plane), and a frozen
/// weight lets the steps drift towards the camera, where the metric residuals shrink. Jw is
/// therefore the exact derivative of rw = r * focal_px / (sigma_px * depth * gain), weight
/// included: d rw = i (dr - r (d depth / depth + d gain / gain)).
inline bool normalised_circle_residual(const Eigen::Vector3d& c, const Eigen::Vector3d& a, double radius,
                                       const Eigen::Vector2d& xn, double sigma_px, const ResidualWeighting& w,
                                       double& rw, Matrix16d* Jw = nullptr) {
  const CircleIntersection ci = circle_residual_at(c, a, radius, xn, Jw);
  if (!ci.valid) return false;
  const bool gain_varies = w.oblique && ci.gain > kMinLineGain;
  const bool depth_varies = ci.depth > w.min_depth;
  const double gain = w.oblique ? std::max(ci.gain, kMinLineGain) : 1.0;
  const double depth = std::max(ci.depth, w.min_depth);
  const double i = w.focal_px / (sigma_px * depth * gain);
  rw = ci.residual * i;
  if (Jw == nullptr) return true;
  // Derivatives of depth = lambda and of gain = |(g_x, g_y)|, g = u - k a (see circle_residual_at).
  const Eigen::Vector3d d(xn.x(), xn.y(), 1.0);
  const double ad = a.dot(d);
  const Eigen::Vector3d X = ci.depth * d, e = X - c;
  const double len = e.norm();
  const Eigen::Vector3d u = e / len;
  const double ud = u.dot(d), k = ud / ad;
  Matrix16d J_lambda;
  J_lambda << a.transpose() / ad, X.cross(a).transpose() / ad;
  Matrix16d J_rel = Matrix16d::Zero();  // d depth / depth + d gain / gain
  if (depth_varies) J_rel += J_lambda / ci.depth;
  if (gain_varies) {
    Matrix36d Jc, Ja = Matrix36d::Zero();
    Jc << Eigen::Matrix3d::Identity(), -geometry::hat(c);  // dc = v + w x c
    Ja.rightCols<3>() = -geometry::hat(a);                  // da = w x a
    const Matrix36d Je = d * J_lambda - Jc;
    const Matrix36d Ju = (Je - u * (u.transpose() * Je)) / len;  // (I - u u^T) Je / |e|
    const Matrix16d Jk = (d.transpose() * Ju * ad - ud * d.transpose() * Ja) / (ad * ad);
    const Matrix36d Jg = Ju - a * Jk - k * Ja;
    const Eigen::Vector3d g = u - k * a;
    J_rel += (g.x() * Jg.row(0) + g.y() * Jg.row(1)) / (ci.gain * ci.gain);
  }
  *Jw = i * (*Jw - ci.residual * J_rel);
  return true;
}

}  // namespace v4r::estimation
