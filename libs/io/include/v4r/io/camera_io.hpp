// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/camera.hpp"

namespace v4r::io {

/// \brief How a calibration file is read.
struct CameraFileOptions {
  /// Accept a file without image_width and image_height: the camera then has width = height = 0
  /// and the caller takes the size from the first image.
  bool size_optional = false;
};

/// \brief Loads a calibration file. YAML formats are recognised by their keys:
/// OpenCV FileStorage YAML (`%YAML:1.0`, `camera_matrix`, `distortion_coefficients`,
/// `image_width`, `image_height`, as OpenCV's calibration tools write them) and ROS
/// `camera_info` YAML (`image_width`, `image_height`, `camera_matrix: {rows, cols, data}`,
/// `distortion_model: plumb_bob`, `distortion_coefficients: {data}`; also the message form
/// `width`, `height`, `K`, `D`). XML files (the text starts with '<') are OpenCV FileStorage XML
/// (`<opencv_storage>` with the same keys) or ViSP's camera parameters (`<root><camera>` with
/// `image_width`, `image_height` and a `<model>` of type perspectiveProjWithDistortion (px, py,
/// u0, v0, kud: k1 = kud) or perspectiveProjWithoutDistortion; the first camera, the model with
/// distortion when both are given). Without distortion coefficients the camera has none.
/// Errors name the file, line and key.
Expected<geometry::PinholeCamera> load_camera(const std::string& path, const CameraFileOptions& opt = {});

/// Parses calibration text (same formats); `source` names it in errors.
Expected<geometry::PinholeCamera> parse_camera(const std::string& text, const std::string& source,
                                               const CameraFileOptions& opt = {});

/// Writes an OpenCV FileStorage YAML calibration file that load_camera (and cv::FileStorage) read.
Expected<void> save_camera_opencv(const std::string& path, const geometry::PinholeCamera& cam);

}  // namespace v4r::io
