// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <memory>
#include <string>

#include "v4r/core/expected.hpp"
#include "v4r/io/frame_source.hpp"

namespace v4r::io {

/// Opens a live camera (see is_live_input). A grabber thread reads frames as fast as the camera
/// delivers them and keeps only the newest; next() hands out that newest frame (waiting for one
/// newer than the last it gave) and counts the ones that were never handed out as dropped.
/// Errors name the device or pipeline: a device that does not exist, one that cannot be opened,
/// an OpenCV without the needed back-end, a pipeline that does not start.
Expected<std::unique_ptr<FrameSource>> open_live(const std::string& input);

}  // namespace v4r::io
