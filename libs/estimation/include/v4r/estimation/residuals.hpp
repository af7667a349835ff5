// v4r - robust model-based object tracking. MIT licence.
#pragma once

// \brief Object-space residuals of the Wunsch pose solver (paper section 5) with analytic
// Jacobians. All residuals are 3-D discrepancies in metres, measured in the camera frame.
//
// Jacobians are with respect to a left update of the pose, T <- exp(delta) * T with
// delta = (v, w) in R^6 (metres, radians). For p = T * X (camera frame) and a small delta,
// exp(delta) * p ~= p + v + w x p, so dp/ddelta = [I3, -hat(p)], and for any fixed direction a,
// d(a . p)/ddelta = [a^T, (p x a)^T].

#include <cmath>

#include <Eigen/Core>

#include "v4r/geometry/se3.hpp"

namespace v4r::estimation {

using Matrix26d = Eigen::Matrix<double, 2, 6>;
using Matrix16d = Eigen::Matrix<double, 1, 6>;

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

}  // namespace v4r::estimation
