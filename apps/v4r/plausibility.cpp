// v4r - robust model-based object tracking. MIT licence.
#include "plausibility.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

namespace v4r::app {

std::vector<std::string> check_pose(const io::PoseNumbers& v, const std::string& source) {
  std::vector<std::string> w;
  const double angle = Eigen::Vector3d(v[3], v[4], v[5]).norm();
  if (angle > plausibility::kMaxRotationVector)
    w.push_back(fmt::format("{}: the rotation vector ({}, {}, {}) is {:.1f} rad long, more than 2 pi: degrees? "
                            "rx ry rz are radians ({:.4g} {:.4g} {:.4g} if those were degrees)",
                            source, v[3], v[4], v[5], angle, v[3] * M_PI / 180.0, v[4] * M_PI / 180.0,
                            v[5] * M_PI / 180.0));
  const double d = Eigen::Vector3d(v[0], v[1], v[2]).norm();
  if (d > plausibility::kMaxDistance)
    w.push_back(fmt::format("{}: the object is {:.4g} m from the camera, beyond {} m: millimetres? tx ty tz are "
                            "metres",
                            source, d, plausibility::kMaxDistance));
  else if (d < plausibility::kMinDistance)
    w.push_back(fmt::format("{}: the object is {:.4g} m from the camera, nearer than {} cm: is the pose in metres?",
                            source, d, plausibility::kMinDistance * 100.0));
  return w;
}

Extent model_extent(const model::Model& m) {
  Extent e;
  e.min.setConstant(std::numeric_limits<double>::infinity());
  e.max.setConstant(-std::numeric_limits<double>::infinity());
  const auto add = [&](const Eigen::Vector3d& p) {
    e.min = e.min.cwiseMin(p);
    e.max = e.max.cwiseMax(p);
  };
  for (const model::Junction& j : m.junctions()) add(j.p);
  for (const model::CircleArc& a : m.arcs()) {
    const Eigen::Vector3d y = a.normal.cross(a.x_axis);
    for (int k = 0; k < 16; ++k) {
      const double t = a.start + (a.end - a.start) * k / 15.0;
      add(a.center + a.radius * (std::cos(t) * a.x_axis + std::sin(t) * y));
    }
  }
  if (!(e.min.array() <= e.max.array()).all()) return Extent{};
  return e;
}

std::vector<std::string> check_model_size(const model::Model& m, const std::string& source) {
  std::vector<std::string> w;
  const double size = model_extent(m).size().maxCoeff();
  if (size > plausibility::kMaxModelSize)
    w.push_back(fmt::format("{}: the model is {:.4g} m across, more than {} m: millimetres? --model-units mm "
                            "(or --mesh-scale 0.001)",
                            source, size, plausibility::kMaxModelSize));
  return w;
}

std::vector<std::string> check_projection(const model::Model& m, const geometry::PinholeCamera& cam,
                                          const geometry::SE3& T) {
  std::vector<std::string> w;
  Eigen::Vector2d lo(std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  int in_front = 0, inside = 0;
  const auto add = [&](const Eigen::Vector3d& p_obj) {
    const Eigen::Vector3d p = T * p_obj;
    if (p.z() <= 1e-6) return;
    ++in_front;
    // Pinhole without distortion: the check is about framing, not sub-pixel accuracy, and far
    // outside the image the distortion polynomial means nothing.
    const Eigen::Vector2d px(cam.fx * p.x() / p.z() + cam.cx, cam.fy * p.y() / p.z() + cam.cy);
    lo = lo.cwiseMin(px);
    hi = hi.cwiseMax(px);
    if (px.x() >= 0 && px.y() >= 0 && px.x() <= cam.width - 1 && px.y() <= cam.height - 1) ++inside;
  };
  for (const model::Junction& j : m.junctions()) add(j.p);
  for (const model::CircleArc& a : m.arcs()) {
    const Eigen::Vector3d y = a.normal.cross(a.x_axis);
    for (int k = 0; k < 8; ++k) {
      const double t = a.start + (a.end - a.start) * k / 7.0;
      add(a.center + a.radius * (std::cos(t) * a.x_axis + std::sin(t) * y));
    }
  }
  if (in_front == 0) {
    w.push_back("at the initial pose the whole model is behind the camera");
    return w;
  }
  if (inside == 0 &&
      (hi.x() < 0 || hi.y() < 0 || lo.x() > cam.width - 1 || lo.y() > cam.height - 1)) {
    w.push_back(fmt::format("at the initial pose the model projects outside the {}x{} image (pixels {:.0f}..{:.0f} "
                            "x {:.0f}..{:.0f}): is the pose T_cam_obj (object in camera frame)?",
                            cam.width, cam.height, lo.x(), hi.x(), lo.y(), hi.y()));
    return w;
  }
  const double size = std::max(hi.x() - lo.x(), hi.y() - lo.y());
  if (size < plausibility::kMinImageSize)
    w.push_back(fmt::format("at the initial pose the model is {:.1f} px across in the image, under {} px: too "
                            "far away to track (distance {:.3g} m)",
                            size, plausibility::kMinImageSize, T.translation().norm()));
  return w;
}

}  // namespace v4r::app
