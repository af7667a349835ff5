// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <array>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/se3.hpp"

namespace v4r::io {

/// \brief The six numbers of a pose as written: tx ty tz (metres), rx ry rz (rotation vector, radians).
using PoseNumbers = std::array<double, 6>;

/// Parses the six numbers of a pose (see parse_pose) without turning them into a pose, so that a
/// caller can check them as given (a rotation vector longer than 2 pi, a distance in millimetres).
Expected<PoseNumbers> parse_pose_numbers(const std::string& text, const std::string& source);

/// Loads the six numbers of a pose file (see load_pose_file).
Expected<PoseNumbers> load_pose_numbers(const std::string& path);

/// The pose T_cam_obj of six numbers.
geometry::SE3 pose_from_numbers(const PoseNumbers& v);

/// The same rotation with qw >= 0 (for qw = 0 the first non-zero of qx, qy, qz positive): the sign
/// every CSV of v4r writes, so that consecutive rows never flip.
Eigen::Quaterniond canonical(const Eigen::Quaterniond& q);

/// \brief Parses "tx ty tz rx ry rz" (T_cam_obj: metres, rotation vector in radians, OpenCV
/// Rodrigues); commas are accepted as separators. `source` names the input in errors.
Expected<geometry::SE3> parse_pose(const std::string& text, const std::string& source);

/// Loads a pose file holding the six numbers above ('#' comments allowed).
Expected<geometry::SE3> load_pose_file(const std::string& path);

/// Writes a pose file of six numbers.
Expected<void> save_pose_file(const std::string& path, const geometry::SE3& T);

/// \brief One row of a ground-truth or pose CSV: frame index and T_cam_obj.
struct PoseRow {
  int frame = 0;
  geometry::SE3 T_cam_obj;
};

/// Reads a CSV with a header containing at least frame,tx,ty,tz,qw,qx,qy,qz (other columns ignored).
Expected<std::vector<PoseRow>> load_pose_csv(const std::string& path);

/// Writes a CSV `frame,tx,ty,tz,qw,qx,qy,qz` (the ground-truth format of `v4r render`).
Expected<void> save_pose_csv(const std::string& path, const std::vector<PoseRow>& rows);

}  // namespace v4r::io
