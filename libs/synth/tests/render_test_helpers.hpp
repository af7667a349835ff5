// v4r - robust model-based object tracking. MIT licence.
// Test support shared by the synth tests: one degree in radians and the median of an image window.
#pragma once

#include <algorithm>
#include <cstdint>
#include <numbers>
#include <vector>

#include <opencv2/core.hpp>

namespace v4r::synth::test {

constexpr double kDeg = std::numbers::pi / 180.0;

/// Median of a (2r+1)^2 window of a grey image.
inline double window_median(const cv::Mat& grey, int x, int y, int r) {
  std::vector<int> v;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) v.push_back(grey.at<std::uint8_t>(y + dy, x + dx));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace v4r::synth::test
