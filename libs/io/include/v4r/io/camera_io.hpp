// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/camera.hpp"

namespace v4r::io {

/// \brief Loads a calibration file. Two formats are recognised by their keys:
/// OpenCV FileStorage YAML (`%YAML:1.0`, `camera_matrix`, `distortion_coefficients`,
/// `image_width`, `image_height`, as OpenCV's calibration tools write them) and ROS
/// `camera_info` YAML (`image_width`, `image_height`, `camera_matrix: {rows, cols, data}`,
/// `distortion_model: plumb_bob`, `distortion_coefficients: {data}`; also the message form
/// `width`, `height`, `K`, `D`). Errors name the file, line and key.
Expected<geometry::PinholeCamera> load_camera(const std::string& path);

/// Parses calibration text (same formats); `source` names it in errors.
Expected<geometry::PinholeCamera> parse_camera(const std::string& text, const std::string& source);

/// Writes an OpenCV FileStorage YAML calibration file that load_camera (and cv::FileStorage) read.
Expected<void> save_camera_opencv(const std::string& path, const geometry::PinholeCamera& cam);

}  // namespace v4r::io
