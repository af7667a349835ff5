// v4r - robust model-based object tracking. MIT licence.
//
// C++17-clean facade of the tracker: this header includes only the standard library, so that
// hosts built as C++17 (ROS 1 nodes: ROS 1 headers do not compile as C++20) can track an object
// without seeing v4r's C++20 headers. The implementation (pimpl) is in the C++20 library v4r::embed.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>

namespace v4r::embed {

/// \brief Pixel layout of an image handed to ObjectTracker::track().
enum class PixelFormat { kMono8, kBgr8, kRgb8 };

/// \brief Pinhole calibration: pixels; distortion k1 k2 p1 p2 k3 (OpenCV / ROS plumb_bob order).
struct CameraIntrinsics {
  int width = 0, height = 0;               ///< pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;   ///< pixels
  std::array<double, 5> dist{0, 0, 0, 0, 0};
};

/// \brief A pose T_cam_obj: translation in metres, unit quaternion (w, x, y, z).
struct Pose {
  std::array<double, 3> t{0, 0, 0};
  std::array<double, 4> q{1, 0, 0, 0};
};

/// \brief The result of one frame.
struct TrackOutput {
  Pose pose;  ///< T_cam_obj: object frame into the camera (optical) frame
  /// 6x6 row-major covariance of the pose on the left tangent (v, w): translation x y z in m^2,
  /// then rotation about x y z in rad^2, in the camera frame (ROS's order).
  std::array<double, 36> covariance{};
  const char* status = "lost";  ///< "tracking", "degraded" or "lost" (static strings)
  double quality = 0.0;         ///< [0, 1]
  double cycle_ms = 0.0;        ///< time of the vision cycle
};

/// \brief Set-up of an ObjectTracker.
struct TrackerOptions {
  std::string model;       ///< .cao or mesh file (OBJ/PLY/STL), lengths in metres after `model_scale`
  double model_scale = 1;  ///< model units -> metres
  std::string config;      ///< YAML of tracker parameters (`v4r config`), empty: defaults
};

/// \brief One object tracked in the images of one camera (v4r's vision cycle behind a pimpl).
/// Not thread-safe: one thread calls it at a time. track() does not allocate once the camera and
/// the image size are stable (the output is written into the caller's struct).
class ObjectTracker {
 public:
  /// Loads the model and the configuration; nullptr with `error` set (naming the file) on failure.
  static std::unique_ptr<ObjectTracker> create(const TrackerOptions& options, std::string& error);
  ~ObjectTracker();
  ObjectTracker(const ObjectTracker&) = delete;
  ObjectTracker& operator=(const ObjectTracker&) = delete;

  /// Sets the calibration; a change rebuilds the tracker (keeping its pose). False with `error`
  /// for an invalid calibration (size or focal length not positive).
  bool set_camera(const CameraIntrinsics& camera, std::string& error);
  [[nodiscard]] bool has_camera() const;
  /// (Re)initialises tracking from T_cam_obj, applied to the next frame.
  void set_pose(const Pose& T_cam_obj);
  [[nodiscard]] bool has_pose() const;
  /// Tracks one image (rows of `step` bytes). False with `error` when there is no camera or pose
  /// yet, or the image does not match the calibration or the format.
  bool track(const std::uint8_t* data, int width, int height, int step, PixelFormat format, double stamp_s,
             TrackOutput& out, std::string& error);

 private:
  struct Impl;
  explicit ObjectTracker(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// Parses "tx ty tz rx ry rz" (metres, Rodrigues rotation vector in radians) into a pose; false
/// with `error` when it is not six finite numbers.
bool parse_pose(const std::string& text, Pose& out, std::string& error);

/// The pose of a translation and a rotation vector (Rodrigues, radians).
Pose pose_from_rvec(const std::array<double, 3>& t, const std::array<double, 3>& rvec);

}  // namespace v4r::embed
