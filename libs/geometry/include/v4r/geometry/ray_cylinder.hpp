// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cmath>

#include <Eigen/Core>

namespace v4r::geometry {

/// \brief Does the ray t * d from the origin (d unit, 0 < t < t_max) pass through a closed
/// cylinder: its side (axis from p1 along the unit `axis` for `length`, radius `radius`) or one
/// of its end caps (discs of radius `cap_radius` at both ends)? Used for hidden-line removal.
inline bool ray_hits_cylinder(const Eigen::Vector3d& d, double t_max, const Eigen::Vector3d& p1,
                              const Eigen::Vector3d& axis, double radius, double length, double cap_radius) {
  // Side: |(t d - p1) - ((t d - p1).a) a| = r, a quadratic in t.
  const Eigen::Vector3d dp = d - d.dot(axis) * axis;
  const Eigen::Vector3d op = -p1 - (-p1).dot(axis) * axis;
  const double A = dp.squaredNorm(), B = 2.0 * dp.dot(op), C = op.squaredNorm() - radius * radius;
  if (A > 1e-12) {
    const double disc = B * B - 4.0 * A * C;
    if (disc > 0.0) {
      const double sq = std::sqrt(disc);
      for (const double t : {(-B - sq) / (2.0 * A), (-B + sq) / (2.0 * A)}) {
        if (t <= 0.0 || t >= t_max) continue;
        const double h = (t * d - p1).dot(axis);
        if (h >= 0.0 && h <= length) return true;
      }
    }
  }
  // Caps: discs at both ends.
  const double den = d.dot(axis);
  if (std::abs(den) > 1e-12) {
    for (const double h : {0.0, length}) {
      const Eigen::Vector3d centre = p1 + h * axis;
      const double t = centre.dot(axis) / den;
      if (t <= 0.0 || t >= t_max) continue;
      if ((t * d - centre).squaredNorm() < cap_radius * cap_radius) return true;
    }
  }
  return false;
}

}  // namespace v4r::geometry
