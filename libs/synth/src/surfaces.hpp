// v4r - robust model-based object tracking. MIT licence.
// Internal to the synth module: the surfaces of one frame, in the camera frame, ready for ray
// casting. A ray is given by normalised undistorted coordinates (x, y): the points (x, y, 1) * z.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"

namespace v4r::synth::detail {

/// Kinds of ray-castable surfaces: planar polygons (model faces), disks (cylinder end caps) and
/// the lateral surface of a finite cylinder.
enum class SurfaceKind : std::uint8_t { kPolygon, kDisk, kCylinderSide };

/// \brief One surface of the model in the camera frame (metres), with its pixel bounding box,
/// albedo and texture mapping. Each surface has its own id in the z-buffer, so that the edges
/// between surfaces (including a cylinder's rims) are supersampled.
struct Surface {
  SurfaceKind kind = SurfaceKind::kPolygon;
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;              ///< pixel bounding box (inclusive)
  Eigen::Vector3f albedo = Eigen::Vector3f::Ones();  ///< BGR, 0..1
  float light = 0;  ///< ambient + diffuse factor (planar surfaces; the side is lit per pixel)

  // Plane n . p = d (polygons and disks); d < 0 for surfaces facing the camera.
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();  ///< unit outward normal
  double d = 0;

  // Polygon.
  std::vector<Eigen::Vector2d> poly;   ///< normalised coordinates (after near clipping)
  std::vector<Eigen::Vector3d> lines;  ///< convex case: a x + b y + c >= 0 inside, per edge
  bool convex = true;

  // Disk.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius2 = 0;  ///< squared radius, m^2

  // Cylinder side: axis from `a` (camera frame, the p1 end) along unit `axis` for `length`.
  Eigen::Vector3d a = Eigen::Vector3d::Zero(), axis = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d q = Eigen::Vector3d::Zero();  ///< component of -a orthogonal to the axis
  Eigen::Vector3d e1 = Eigen::Vector3d::UnitX(), e2 = Eigen::Vector3d::UnitY();  ///< angular reference
  double a_axis = 0;                                                             ///< a . axis
  double c0 = 0;  ///< q . q - radius^2 (> 0: the camera is outside the infinite cylinder)
  double length = 0, radius = 0;

  // Texture: planar surfaces map p (camera frame) to texels (tu . p + tu0, tv . p + tv0); the
  // side maps (angle, height) to (tex_around * angle / 2 pi + tu0, tex_per_m * height + tv0).
  Eigen::Vector3d tu = Eigen::Vector3d::Zero(), tv = Eigen::Vector3d::Zero();
  double tu0 = 0, tv0 = 0;
  double tex_around = 0, tex_per_m = 0;

  [[nodiscard]] bool in_box(int x, int y) const { return x >= x0 && x <= x1 && y >= y0 && y <= y1; }

  [[nodiscard]] bool contains(double x, double y) const {
    if (convex) {
      for (const Eigen::Vector3d& l : lines)
        if (l.x() * x + l.y() * y + l.z() < 0.0) return false;
      return true;
    }
    bool in = false;  // crossing number
    for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
      const Eigen::Vector2d& pa = poly[i];
      const Eigen::Vector2d& pb = poly[j];
      if ((pa.y() > y) != (pb.y() > y) && x < (pb.x() - pa.x()) * (y - pa.y()) / (pb.y() - pa.y()) + pa.x()) in = !in;
    }
    return in;
  }
  /// Depth (z, metres) where the ray meets the plane (polygons and disks).
  [[nodiscard]] double plane_depth(double x, double y) const { return d / (n.x() * x + n.y() * y + n.z()); }

  [[nodiscard]] bool hit_polygon(double x, double y, double& z) const {
    if (!contains(x, y)) return false;
    z = plane_depth(x, y);
    return z > 0.0;
  }
  [[nodiscard]] bool hit_disk(double x, double y, double& z) const {
    z = plane_depth(x, y);
    if (!(z > 0.0)) return false;
    const double dx = x * z - centre.x(), dy = y * z - centre.y(), dz = z - centre.z();
    return dx * dx + dy * dy + dz * dz <= radius2;
  }
  /// Nearest intersection with the finite lateral surface, seen from outside: the ray (s w, w =
  /// (x, y, 1)) meets the infinite cylinder where |s W + q|^2 = r^2, W = w - (w . axis) axis,
  /// i.e. s^2 (w.w - (w.axis)^2) + 2 s (w . q) + c0 = 0; the hit counts if 0 <= height <= length.
  [[nodiscard]] bool hit_side(double x, double y, double& z) const {
    const double wa = x * axis.x() + y * axis.y() + axis.z();
    const double A = x * x + y * y + 1.0 - wa * wa;
    const double B = x * q.x() + y * q.y() + q.z();
    const double disc = B * B - A * c0;
    if (disc < 0.0 || !(A > 0.0)) return false;
    z = (-B - std::sqrt(disc)) / A;
    if (!(z > 0.0)) return false;
    const double h = z * wa - a_axis;
    return h >= 0.0 && h <= length;
  }
  [[nodiscard]] bool hit(double x, double y, double& z) const {
    switch (kind) {
      case SurfaceKind::kPolygon:
        return hit_polygon(x, y, z);
      case SurfaceKind::kDisk:
        return hit_disk(x, y, z);
      case SurfaceKind::kCylinderSide:
        return hit_side(x, y, z);
    }
    return false;
  }
};

/// What build_surfaces needs besides the model and the pose.
struct SurfaceSetup {
  const geometry::PinholeCamera* cam = nullptr;
  cv::Rect2d ray_bounds;          ///< normalised region covered by the image's rays
  double texels_per_metre = 1.0;  ///< texture scale
  std::uint32_t seed = 0;         ///< albedo variation and texture offsets
};

/// The front-facing surfaces of `model` at pose T_cam_obj that may be visible in the image: faces
/// (clipped at the near plane), and per cylinder its side and its end disks that face the camera.
/// `light` is left at 0 (see light_surfaces).
std::vector<Surface> build_surfaces(const model::Model& model, const geometry::SE3& T_cam_obj,
                                    const SurfaceSetup& setup);

/// Sets the flat light factor ambient + (1 - ambient) max(0, n . light) of the planar surfaces.
void light_surfaces(std::vector<Surface>& surfaces, const Eigen::Vector3d& light_unit, double ambient);

}  // namespace v4r::synth::detail
