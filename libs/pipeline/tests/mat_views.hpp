// v4r - robust model-based object tracking. MIT licence.
// Views of 8-bit cv::Mat images for the pipeline tests (no copy; the Mat must outlive the view).
#pragma once

#include <cstdint>

#include <opencv2/core.hpp>

#include "v4r/image/colour_view.hpp"
#include "v4r/image/image_view.hpp"

namespace v4r::test {

inline image::ImageView view(const cv::Mat& g) {
  return {g.ptr<std::uint8_t>(0), g.cols, g.rows, static_cast<int>(g.step[0])};
}
inline image::ColourView cview(const cv::Mat& c) {
  return {c.ptr<std::uint8_t>(0), c.cols, c.rows, static_cast<int>(c.step[0])};
}

}  // namespace v4r::test
