// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include <opencv2/core.hpp>

#include "v4r/core/expected.hpp"
#include "v4r/image/colour_view.hpp"
#include "v4r/image/image_view.hpp"

namespace v4r::io {

/// \brief A sequence of input frames: a folder of images (sorted by name), a printf pattern
/// (`frames/%06d.png`, counted from 0 or from the first index that exists), a video file, or a
/// live camera: `/dev/videoN` (V4L2) or `gst:PIPELINE` (a GStreamer pipeline; an appsink is
/// appended when it has none). Live sources hand out the newest frame and drop the ones the
/// caller was too slow for (dropped()).
class FrameSource {
 public:
  virtual ~FrameSource() = default;

  /// Opens INPUT; errors name it (missing, empty folder, unreadable video, missing camera...).
  static Expected<std::unique_ptr<FrameSource>> open(const std::string& input);

  /// Reads the next frame into `bgr` (8-bit, 1 or 3 channels as stored). Returns false at the
  /// end of the input, or an Error naming the frame that could not be decoded.
  virtual Expected<bool> next(cv::Mat& bgr) = 0;
  /// Name of the last frame read (file path, or "video.mp4#12").
  [[nodiscard]] virtual std::string current_name() const = 0;
  /// Number of frames if known, else -1.
  [[nodiscard]] virtual int size_hint() const = 0;
  /// The frame rate the input declares (a video's own rate), or 0 when it declares none.
  [[nodiscard]] virtual double nominal_fps() const { return 0.0; }
  /// Modification time of the last frame's file, seconds since the epoch (sub-second where the
  /// file system keeps it), or a negative number when the frame has no file of its own (video).
  [[nodiscard]] virtual double file_time_s() const { return -1.0; }
  /// True for a live camera: frames come at the camera's rate, the newest one is handed out.
  [[nodiscard]] virtual bool live() const { return false; }
  /// When the last frame was captured (steady clock, seconds), or a negative number for inputs
  /// that are not live.
  [[nodiscard]] virtual double capture_time_s() const { return -1.0; }
  /// Frames a live source received but never handed out because a newer one came first.
  [[nodiscard]] virtual std::int64_t dropped() const { return 0; }
  /// The last frame's own time stamp (seconds since the epoch, e.g. a ROS message header), or a
  /// negative number when frames carry none.
  [[nodiscard]] virtual double stamp_s() const { return -1.0; }

  /// Opens the inputs whose name starts with a registered prefix (middleware modules register
  /// theirs, e.g. "ros2:"); consulted by open() before anything else.
  using Opener = std::function<Expected<std::unique_ptr<FrameSource>>(const std::string& input)>;
  /// Registers (or replaces) the opener of inputs starting with `prefix`. Call at start-up.
  static void register_scheme(const std::string& prefix, Opener opener);
};

/// True for inputs that name a live camera: `/dev/videoN` (V4L2) or `gst:PIPELINE` (GStreamer).
bool is_live_input(const std::string& input);

/// View of an 8-bit single-channel cv::Mat (no copy; the Mat must outlive the view).
inline image::ImageView as_view(const cv::Mat& grey) {
  return image::ImageView{grey.ptr<std::uint8_t>(0), grey.cols, grey.rows, static_cast<int>(grey.step[0])};
}

/// View of an 8-bit 3-channel BGR cv::Mat (no copy), or an empty view for any other type.
inline image::ColourView as_colour_view(const cv::Mat& bgr) {
  if (bgr.empty() || bgr.type() != CV_8UC3) return {};
  return image::ColourView{bgr.ptr<std::uint8_t>(0), bgr.cols, bgr.rows, static_cast<int>(bgr.step[0])};
}

}  // namespace v4r::io
