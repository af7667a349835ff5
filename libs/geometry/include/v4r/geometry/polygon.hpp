// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>

#include <Eigen/Core>

namespace v4r::geometry {

/// \brief Crossing-number point-in-polygon test: is q inside the polygon of n vertices (either
/// orientation, not necessarily convex)?
inline bool inside_polygon(const Eigen::Vector2d& q, const Eigen::Vector2d* poly, std::uint32_t n) {
  bool in = false;
  for (std::uint32_t i = 0, j = n - 1; i < n; j = i++) {
    const Eigen::Vector2d& a = poly[i];
    const Eigen::Vector2d& b = poly[j];
    if ((a.y() > q.y()) != (b.y() > q.y())) {
      const double x = a.x() + (q.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (q.x() < x) in = !in;
    }
  }
  return in;
}

}  // namespace v4r::geometry
