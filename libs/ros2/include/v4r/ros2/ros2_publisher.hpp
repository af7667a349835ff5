// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "v4r/core/expected.hpp"

namespace v4r::server {
struct FrameEvents;
}

namespace v4r::ros2 {

/// \brief Where and how `v4r serve --ros2` publishes.
struct Ros2Options {
  int domain = 0;                                ///< DDS domain id (ROS_DOMAIN_ID), 0..232
  std::string ns = "/v4r";                       ///< ROS namespace of the per-object topics ("/" for none)
  std::string frame_id = "camera_optical_frame";  ///< frame id of every header (the camera's optical frame)
  std::size_t max_objects = 64;                  ///< objects published at most (buffers sized once)
};

/// Checks a ROS namespace: "/" or "/" followed by names of [A-Za-z0-9_] separated by "/"
/// (none starting with a digit). The error names the option.
Expected<void> check_namespace(const std::string& ns);

/// ROS name of an object (characters outside [A-Za-z0-9_] become '_', a leading digit gets a '_').
std::string ros_name(const std::string& object);

/// \brief ROS 2 on the wire, through Cyclone DDS with no ROS 2 installed: for each tracked
/// object `geometry_msgs/msg/PoseWithCovarianceStamped` on `<ns>/<object>/pose` and
/// `std_msgs/msg/String` (the track status) on `<ns>/<object>/status`, and every pose on `/tf`
/// (`tf2_msgs/msg/TFMessage`, frame_id -> object). DDS topics `rt/...`, plain CDR, QoS RELIABLE /
/// VOLATILE / KEEP_LAST 10 (`/tf`: KEEP_LAST 100, as tf2 uses). Headers carry the frame's stamp
/// and `frame_id`; the covariance is v4r's, row-major x y z then rotation about x y z (ROS's
/// order). Cyclone's own configuration (CYCLONEDDS_URI) applies.
class Ros2Publisher {
 public:
  /// Creates the participant and the /tf writer; errors name the domain or namespace.
  static Expected<std::unique_ptr<Ros2Publisher>> create(const Ros2Options& options);
  ~Ros2Publisher();
  Ros2Publisher(const Ros2Publisher&) = delete;
  Ros2Publisher& operator=(const Ros2Publisher&) = delete;

  /// Publishes one frame's poses (call from one thread at a time; never blocks for long, never
  /// throws). An object's topics are created the first time it appears.
  void publish(const server::FrameEvents& frame) noexcept;
  /// Pose messages written so far.
  [[nodiscard]] std::uint64_t poses_published() const;
  /// Write errors so far (DDS return codes other than OK), and objects beyond max_objects.
  [[nodiscard]] std::uint64_t errors() const;

 private:
  struct Impl;
  explicit Ros2Publisher(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace v4r::ros2
