// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <chrono>
#include <memory>
#include <string>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/io/frame_source.hpp"

namespace v4r::ros2 {

/// How long an image input waits for a message: before the first image this is an error, after
/// it the end of the input (the publisher stopped).
inline constexpr std::chrono::seconds kImageTimeout{5};

/// Opens `ros2:/camera`: ROS 2 images (`sensor_msgs/msg/Image`, mono8, bgr8 or rgb8) from DDS
/// topic `rt/camera/image_raw` of `domain`, BEST_EFFORT (any publisher matches) and KEEP_LAST 1:
/// the newest image first. Frames carry the header's stamp (stamp_s()). Errors name the input.
Expected<std::unique_ptr<io::FrameSource>> open_image_source(const std::string& input, int domain);

/// Makes io::FrameSource::open() read `ros2:...` inputs through open_image_source(domain).
void register_image_input(int domain);

/// Waits up to `timeout` for a `sensor_msgs/msg/CameraInfo` on `rt/camera/camera_info` (for input
/// `ros2:/camera`; BEST_EFFORT) and returns its calibration (K, plumb_bob D, size).
Expected<geometry::PinholeCamera> wait_camera_info(const std::string& input, int domain,
                                                   std::chrono::milliseconds timeout);

}  // namespace v4r::ros2
