// v4r - robust model-based object tracking. MIT licence.
//
// Live cameras: V4L2 devices (`/dev/videoN`) and GStreamer pipelines (`gst:PIPELINE`), both
// through OpenCV's VideoCapture. A camera delivers frames at its own rate whether or not the
// tracker keeps up, so a grabber thread reads them all and keeps only the newest one: the tracker
// always works on the most recent image and never on a backlog.

#include "live_source.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <opencv2/videoio/registry.hpp>
#include <stop_token>
#include <string_view>
#include <system_error>
#include <thread>
#include <utility>

namespace v4r::io {
namespace {

constexpr std::string_view kGstPrefix = "gst:";
constexpr std::string_view kDevicePrefix = "/dev/video";
/// A live source that delivers no frame for this long is reported as an error by next().
constexpr std::chrono::seconds kNoFrameTimeout{10};

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// \brief A camera read by a grabber thread that keeps only the newest frame (see open_live).
class LiveSource final : public FrameSource {
 public:
  LiveSource(std::unique_ptr<cv::VideoCapture> cap, std::string name) : cap_(std::move(cap)), name_(std::move(name)) {
    const double fps = cap_->get(cv::CAP_PROP_FPS);
    fps_ = (std::isfinite(fps) && fps > 0.0 && fps <= 10000.0) ? fps : 0.0;
    grabber_ = std::jthread([this](std::stop_token st) { grab(st); });
  }
  ~LiveSource() override {
    grabber_.request_stop();
    grabber_.join();  // read() of a live camera returns within a frame period
  }
  LiveSource(const LiveSource&) = delete;
  LiveSource& operator=(const LiveSource&) = delete;

  Expected<bool> next(cv::Mat& bgr) override {
    std::unique_lock lock(mutex_);
    const bool got = fresh_.wait_for(lock, kNoFrameTimeout, [&] { return grabbed_ > taken_ || ended_; });
    if (grabbed_ > taken_) {
      dropped_ += grabbed_ - taken_ - 1;
      taken_ = grabbed_;
      capture_s_ = latest_stamp_s_;
      latest_.copyTo(bgr);  // reuses bgr's buffer when the size is unchanged
      lock.unlock();
      ++index_;
      return true;
    }
    if (!got) return Error{fmt::format("no frame from {} for {} s", name_, kNoFrameTimeout.count()), name_, 0, 0, {}};
    if (!error_.empty()) return Error{error_, name_, 0, 0, {}};
    return false;
  }
  [[nodiscard]] std::string current_name() const override { return fmt::format("{}#{}", name_, index_ - 1); }
  [[nodiscard]] int size_hint() const override { return -1; }
  [[nodiscard]] double nominal_fps() const override { return fps_; }
  [[nodiscard]] bool live() const override { return true; }
  [[nodiscard]] double capture_time_s() const override { return capture_s_; }
  [[nodiscard]] std::int64_t dropped() const override {
    std::scoped_lock lock(mutex_);
    return dropped_;
  }

 private:
  void grab(std::stop_token st) {
    cv::Mat frame, converted;
    while (!st.stop_requested()) {
      bool ok = false;
      std::string error;
      try {
        ok = cap_->read(frame) && !frame.empty();
      } catch (const cv::Exception& e) {
        error = fmt::format("cannot read from {}: {}", name_, e.what());
      }
      const double stamp = steady_seconds();
      if (ok && frame.depth() != CV_8U) {
        frame.convertTo(converted, CV_8U);
        std::swap(frame, converted);
      }
      if (ok && frame.channels() == 4) {
        cv::cvtColor(frame, converted, cv::COLOR_BGRA2BGR);
        std::swap(frame, converted);
      }
      {
        std::scoped_lock lock(mutex_);
        if (!ok) {
          ended_ = true;
          error_ = std::move(error);
        } else {
          std::swap(frame, latest_);  // the grabber never writes into the frame next() copies from
          latest_stamp_s_ = stamp;
          ++grabbed_;
        }
      }
      fresh_.notify_all();
      if (!ok) break;
    }
    cap_->release();
  }

  std::unique_ptr<cv::VideoCapture> cap_;
  std::string name_;
  double fps_ = 0.0;
  std::jthread grabber_;

  mutable std::mutex mutex_;  // guards the fields below up to the consumer's
  std::condition_variable fresh_;
  cv::Mat latest_;
  double latest_stamp_s_ = -1.0;
  std::int64_t grabbed_ = 0, taken_ = 0, dropped_ = 0;
  bool ended_ = false;
  std::string error_;

  // The consumer's (next()'s caller's) own.
  std::int64_t index_ = 0;
  double capture_s_ = -1.0;
};

Expected<std::unique_ptr<FrameSource>> open_device(const std::string& device) {
  std::error_code ec;
  if (!std::filesystem::exists(device, ec))
    return Error{fmt::format("camera device {} does not exist", device), device, 0, 0, {}};
  if (!cv::videoio_registry::hasBackend(cv::CAP_V4L2))
    return Error{fmt::format("cannot open camera {}: this OpenCV has no V4L2 support", device), device, 0, 0, {}};
  auto cap = std::make_unique<cv::VideoCapture>();
  try {
    cap->open(device, cv::CAP_V4L2);
  } catch (const cv::Exception& e) {
    return Error{fmt::format("cannot open camera {}: {}", device, e.what()), device, 0, 0, {}};
  }
  if (!cap->isOpened())
    return Error{fmt::format("cannot open camera {} (not a capture device, busy, or no permission)", device), device,
                 0, 0, {}};
  return std::unique_ptr<FrameSource>(std::make_unique<LiveSource>(std::move(cap), device));
}

Expected<std::unique_ptr<FrameSource>> open_pipeline(const std::string& input) {
  std::string pipeline = input.substr(kGstPrefix.size());
  if (pipeline.find_first_not_of(" \t") == std::string::npos)
    return Error{"empty GStreamer pipeline after 'gst:'", input, 0, 0, {}};
  if (!cv::videoio_registry::hasBackend(cv::CAP_GSTREAMER))
    return Error{"cannot open a GStreamer pipeline: this OpenCV has no GStreamer support", input, 0, 0, {}};
  // OpenCV takes frames from an appsink: one is added (after a videoconvert to BGR) when the
  // pipeline does not end in its own.
  if (pipeline.find("appsink") == std::string::npos) pipeline += " ! videoconvert ! appsink";
  auto cap = std::make_unique<cv::VideoCapture>();
  // OpenCV warns on stderr that a live stream has no duration or position; failures are
  // reported below in one line of ours.
  const cv::utils::logging::LogLevel level = cv::utils::logging::getLogLevel();
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
  try {
    cap->open(pipeline, cv::CAP_GSTREAMER);
  } catch (const cv::Exception& e) {
    cv::utils::logging::setLogLevel(level);
    return Error{fmt::format("cannot start GStreamer pipeline '{}': {}", pipeline, e.what()), input, 0, 0, {}};
  }
  cv::utils::logging::setLogLevel(level);
  if (!cap->isOpened())
    return Error{fmt::format("cannot start GStreamer pipeline '{}' (check it with gst-launch-1.0)", pipeline), input, 0,
                 0, {}};
  return std::unique_ptr<FrameSource>(std::make_unique<LiveSource>(std::move(cap), input));
}

}  // namespace

bool is_live_input(const std::string& input) {
  return input.starts_with(kGstPrefix) || input.starts_with(kDevicePrefix);
}

Expected<std::unique_ptr<FrameSource>> open_live(const std::string& input) {
  if (input.starts_with(kGstPrefix)) return open_pipeline(input);
  return open_device(input);
}

}  // namespace v4r::io
