// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cmath>

#include "v4r/geometry/se3.hpp"

namespace v4r::geometry {

/// \brief Pose T_cam_obj of a camera at `eye_obj` (object frame, metres) looking at
/// `target_obj`, with `up_obj` pointing up in the image (camera -y). `up_obj` must not be
/// parallel to the viewing direction.
inline SE3 look_at(const Eigen::Vector3d& eye_obj, const Eigen::Vector3d& target_obj,
                   const Eigen::Vector3d& up_obj = Eigen::Vector3d::UnitZ()) {
  // Columns of R_obj_cam: camera x (right), y (down), z (forward) in the object frame.
  const Eigen::Vector3d z = (target_obj - eye_obj).normalized();
  Eigen::Vector3d down = -up_obj + up_obj.dot(z) * z;
  if (down.norm() < 1e-9) down = z.unitOrthogonal();
  const Eigen::Vector3d y = down.normalized();
  const Eigen::Vector3d x = y.cross(z);
  Eigen::Matrix3d R_obj_cam;
  R_obj_cam.col(0) = x;
  R_obj_cam.col(1) = y;
  R_obj_cam.col(2) = z;
  return SE3(R_obj_cam, eye_obj).inverse();
}

/// \brief T_cam_obj of a camera at `distance` metres from `target` (object frame), seen from
/// `azimuth` (about the object's z axis, radians, 0 = from +x) and `elevation` (above the
/// object's x-y plane, radians), with the object's +z up in the image. Requires |elevation| < pi/2.
inline SE3 look_at(double distance, double azimuth, double elevation,
                   const Eigen::Vector3d& target = Eigen::Vector3d::Zero()) {
  const Eigen::Vector3d eye = target + distance * Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                                                 std::cos(elevation) * std::sin(azimuth),
                                                                 std::sin(elevation));
  return look_at(eye, target);
}

}  // namespace v4r::geometry
