// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <span>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "v4r/detection/detector_params.hpp"
#include "v4r/geometry/se3.hpp"

namespace v4r::detection {

/// T_cam_obj with the camera turned about its centre until the object-frame point `centre` lies
/// on the optical axis (in front of the camera): the view a template of the pose holds
/// (pose_at_pixel turns it back). `centre` must not project to the camera centre itself.
[[nodiscard]] geometry::SE3 on_axis(const geometry::SE3& T_cam_obj, const Eigen::Vector3d& centre);

/// True when T_cam_obj, or one of its equivalents under the model's `symmetries`, sees the model
/// from within `range` (resolved: resolve_view_range) widened by `margin_deg`: the camera's
/// elevation above the object's x-y plane, seen from the bounding box centre `centre`, within
/// elevation_min/max +- margin; its distance within distance_min/max widened by a factor
/// 1 + margin / 45 deg; and the image's turn about the optical axis within inplane_min/max +-
/// inplane_margin, with the camera turned about its centre until the model's centre lies on the optical
/// axis (not tested when the object's z axis points nearly along the line of sight). The azimuth
/// is not tested.
[[nodiscard]] bool in_view_range(const ViewRange& range, const Eigen::Vector3d& centre,
                                 std::span<const geometry::SE3> symmetries, const geometry::SE3& T_cam_obj,
                                 double margin_deg, double inplane_margin_deg);

}  // namespace v4r::detection
