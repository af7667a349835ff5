// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <array>
#include <optional>

#include <Eigen/Core>

namespace v4r::geometry {

/// \brief Pinhole camera with OpenCV's radial-tangential distortion (k1, k2, p1, p2, k3).
///
/// Camera frame: x right, y down, z forward (OpenCV). Pixel centres are at integer coordinates:
/// pixel (0,0) covers [-0.5, 0.5] x [-0.5, 0.5]. "Normalised" coordinates are undistorted
/// (x/z, y/z) of a point in the camera frame.
struct PinholeCamera {
  int width = 0;   ///< pixels
  int height = 0;  ///< pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  ///< pixels
  std::array<double, 5> dist{0, 0, 0, 0, 0};  ///< k1 k2 p1 p2 k3 (OpenCV order)

  [[nodiscard]] bool has_distortion() const {
    return dist[0] != 0 || dist[1] != 0 || dist[2] != 0 || dist[3] != 0 || dist[4] != 0;
  }

  /// Apply distortion to normalised coordinates (OpenCV model).
  [[nodiscard]] Eigen::Vector2d distort(const Eigen::Vector2d& xn) const {
    const double x = xn.x(), y = xn.y();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (dist[0] + r2 * (dist[1] + r2 * dist[4]));
    const double xd = x * radial + 2.0 * dist[2] * x * y + dist[3] * (r2 + 2.0 * x * x);
    const double yd = y * radial + dist[2] * (r2 + 2.0 * y * y) + 2.0 * dist[3] * x * y;
    return {xd, yd};
  }

  /// The derivative of distort() at `xn`: d(distorted) / d(normalised).
  [[nodiscard]] Eigen::Matrix2d distort_jacobian(const Eigen::Vector2d& xn) const {
    const double x = xn.x(), y = xn.y();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (dist[0] + r2 * (dist[1] + r2 * dist[4]));
    const double dradial = dist[0] + r2 * (2.0 * dist[1] + 3.0 * r2 * dist[4]);  // d radial / d r2
    const double cross = 2.0 * x * y * dradial + 2.0 * dist[2] * x + 2.0 * dist[3] * y;
    Eigen::Matrix2d J;
    J << radial + 2.0 * x * x * dradial + 2.0 * dist[2] * y + 6.0 * dist[3] * x, cross,  //
        cross, radial + 2.0 * y * y * dradial + 6.0 * dist[2] * y + 2.0 * dist[3] * x;
    return J;
  }

  /// Normalised (undistorted) coordinates -> pixel.
  [[nodiscard]] Eigen::Vector2d normalized_to_pixel(const Eigen::Vector2d& xn) const {
    const Eigen::Vector2d d = has_distortion() ? distort(xn) : xn;
    return {fx * d.x() + cx, fy * d.y() + cy};
  }

  /// Point in camera frame (metres, z > 0) -> pixel.
  [[nodiscard]] Eigen::Vector2d project(const Eigen::Vector3d& p_cam) const {
    return normalized_to_pixel(Eigen::Vector2d(p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z()));
  }

  /// Pixel -> normalised undistorted coordinates (fixed-point iteration, as OpenCV does).
  [[nodiscard]] Eigen::Vector2d pixel_to_normalized(const Eigen::Vector2d& px) const {
    const Eigen::Vector2d xd((px.x() - cx) / fx, (px.y() - cy) / fy);
    if (!has_distortion()) return xd;
    Eigen::Vector2d x = xd;
    for (int i = 0; i < 20; ++i) {
      const double r2 = x.squaredNorm();
      const double radial = 1.0 + r2 * (dist[0] + r2 * (dist[1] + r2 * dist[4]));
      const double dx = 2.0 * dist[2] * x.x() * x.y() + dist[3] * (r2 + 2.0 * x.x() * x.x());
      const double dy = dist[2] * (r2 + 2.0 * x.y() * x.y()) + 2.0 * dist[3] * x.x() * x.y();
      const Eigen::Vector2d next((xd.x() - dx) / radial, (xd.y() - dy) / radial);
      const double step = (next - x).squaredNorm();
      x = next;
      if (step < 1e-24) break;  // converged to ~1e-12 (normalised units)
    }
    return x;
  }

  /// Mean focal length, pixels (converts object-space errors to pixels: px = f * e / z).
  [[nodiscard]] double focal() const { return 0.5 * (fx + fy); }

  [[nodiscard]] bool in_image(const Eigen::Vector2d& px, double margin = 0.0) const {
    return px.x() >= -0.5 + margin && px.y() >= -0.5 + margin && px.x() <= width - 0.5 - margin &&
           px.y() <= height - 0.5 - margin;
  }
};

}  // namespace v4r::geometry
