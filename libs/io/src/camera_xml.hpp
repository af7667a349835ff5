// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/io/camera_io.hpp"

namespace v4r::io {

/// \brief Parses an XML calibration: OpenCV FileStorage XML (`<opencv_storage>`) or ViSP's camera
/// parameters (`<root><camera>`). See load_camera. Errors name the source, line, column and element.
Expected<geometry::PinholeCamera> parse_camera_xml(const std::string& text, const std::string& source,
                                                   const CameraFileOptions& opt);

}  // namespace v4r::io
