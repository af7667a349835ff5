// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cmath>

#include "v4r/geometry/se3.hpp"

namespace v4r::geometry {

/// \brief T_cam_obj of a camera at `distance` metres from `target` (object frame), seen from
/// `azimuth` (about the object's z axis, radians, 0 = from +x) and `elevation` (above the
/// object's x-y plane, radians), looking at the target with the object's +z pointing up in the
/// image. Requires |elevation| < pi/2.
inline SE3 look_at(double distance, double azimuth, double elevation,
                   const Eigen::Vector3d& target = Eigen::Vector3d::Zero()) {
  const Eigen::Vector3d c = target + distance * Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                                               std::cos(elevation) * std::sin(azimuth),
                                                               std::sin(elevation));
  const Eigen::Vector3d z = (target - c).normalized();               // forward
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();  // right
  const Eigen::Vector3d y = z.cross(x);                              // down
  Eigen::Matrix3d R_obj_cam;
  R_obj_cam.col(0) = x;
  R_obj_cam.col(1) = y;
  R_obj_cam.col(2) = z;
  return SE3(R_obj_cam, c).inverse();
}

}  // namespace v4r::geometry
