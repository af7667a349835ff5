// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "v4r/io/frame_source.hpp"

namespace v4r::io {

/// \brief An endless input: the given frames (at least one), in turn, without end. For benchmarks
/// and tests of the server on a static scene (a few renders with different sensor noise).
class LoopSource final : public FrameSource {
 public:
  explicit LoopSource(std::vector<cv::Mat> frames) : frames_(std::move(frames)) {}
  Expected<bool> next(cv::Mat& bgr) override {
    if (frames_.empty()) return false;
    bgr = frames_[static_cast<std::size_t>(index_++) % frames_.size()];
    return true;
  }
  [[nodiscard]] std::string current_name() const override { return "loop#" + std::to_string(index_); }
  [[nodiscard]] int size_hint() const override { return -1; }

 private:
  std::vector<cv::Mat> frames_;
  long index_ = 0;
};

}  // namespace v4r::io
