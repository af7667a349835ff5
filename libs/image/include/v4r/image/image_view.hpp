// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>

namespace v4r::image {

/// \brief Non-owning view of an 8-bit grey image (row-major, `stride` bytes between rows).
/// Pixel centres are at integer coordinates.
struct ImageView {
  const std::uint8_t* data = nullptr;
  int width = 0;
  int height = 0;
  int stride = 0;  ///< bytes per row

  [[nodiscard]] bool empty() const { return data == nullptr || width <= 0 || height <= 0; }
  [[nodiscard]] std::uint8_t at(int x, int y) const { return data[static_cast<long>(y) * stride + x]; }

  /// Bilinear sample at (x, y); coordinates are clamped to the image.
  [[nodiscard]] float sample(double x, double y) const {
    if (x < 0.0) x = 0.0;
    if (y < 0.0) y = 0.0;
    const double xmax = width - 1.0001, ymax = height - 1.0001;
    if (x > xmax) x = xmax;
    if (y > ymax) y = ymax;
    return sample_inside(x, y);
  }

  /// Bilinear sample without clamping: the caller guarantees 0 <= x < width - 1 and
  /// 0 <= y < height - 1 (the four neighbours exist).
  [[nodiscard]] float sample_inside(double x, double y) const {
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const float ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
    const std::uint8_t* r0 = data + static_cast<long>(y0) * stride + x0;
    const std::uint8_t* r1 = r0 + stride;
    const float top = r0[0] + ax * (static_cast<float>(r0[1]) - r0[0]);
    const float bot = r1[0] + ax * (static_cast<float>(r1[1]) - r1[0]);
    return top + ay * (bot - top);
  }

  /// True when (x, y) lies inside the image with `margin` pixels to spare.
  [[nodiscard]] bool contains(double x, double y, double margin = 0.0) const {
    return x >= margin && y >= margin && x <= width - 1 - margin && y <= height - 1 - margin;
  }
};

}  // namespace v4r::image
