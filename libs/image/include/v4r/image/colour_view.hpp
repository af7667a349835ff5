// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>

#include "v4r/image/image_view.hpp"

namespace v4r::image {

/// \brief Non-owning view of an 8-bit colour image: 3 interleaved channels in B, G, R order (the
/// layout of OpenCV's CV_8UC3), row-major, `stride` bytes between rows. Pixel centres are at
/// integer coordinates, as in ImageView.
struct ColourView {
  static constexpr int kChannels = 3;  ///< bytes per pixel: B, G, R

  const std::uint8_t* data = nullptr;
  int width = 0;
  int height = 0;
  int stride = 0;  ///< bytes per row (at least 3 * width)

  [[nodiscard]] bool empty() const { return data == nullptr || width <= 0 || height <= 0; }
  /// First byte (B) of pixel (x, y); G and R follow.
  [[nodiscard]] const std::uint8_t* pixel(int x, int y) const {
    return data + static_cast<long>(y) * stride + static_cast<long>(x) * kChannels;
  }

  /// Bilinear sample of the three channels at (x, y), written to bgr[0..2] (grey levels);
  /// coordinates are clamped to the image, as ImageView::sample does.
  void sample(double x, double y, float bgr[3]) const {
    if (x < 0.0) x = 0.0;
    if (y < 0.0) y = 0.0;
    const double xmax = width - 1.0001, ymax = height - 1.0001;
    if (x > xmax) x = xmax;
    if (y > ymax) y = ymax;
    sample_inside(x, y, bgr);
  }

  /// Bilinear sample without clamping: the caller guarantees 0 <= x < width - 1 and
  /// 0 <= y < height - 1 (the four neighbours exist).
  void sample_inside(double x, double y, float bgr[3]) const {
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const float ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
    const std::uint8_t* r0 = pixel(x0, y0);
    const std::uint8_t* r1 = r0 + stride;
    for (int c = 0; c < kChannels; ++c) {
      const float top = r0[c] + ax * (static_cast<float>(r0[c + kChannels]) - r0[c]);
      const float bot = r1[c] + ax * (static_cast<float>(r1[c + kChannels]) - r1[c]);
      bgr[c] = top + ay * (bot - top);
    }
  }

  /// True when (x, y) lies inside the image with `margin` pixels to spare.
  [[nodiscard]] bool contains(double x, double y, double margin = 0.0) const {
    return x >= margin && y >= margin && x <= width - 1 - margin && y <= height - 1 - margin;
  }
};

/// Grey level of a B, G, R triple: ITU-R BT.601 luma, Y = 0.299 R + 0.587 G + 0.114 B, in 8-bit
/// fixed point (weights 77, 150, 29 over 256, rounded to nearest).
[[nodiscard]] inline std::uint8_t grey_of(std::uint8_t b, std::uint8_t g, std::uint8_t r) {
  return static_cast<std::uint8_t>((29u * b + 150u * g + 77u * r + 128u) >> 8);
}

/// Converts `colour` to grey (grey_of per pixel) into a caller-owned buffer of at least
/// `out_stride * colour.height` bytes, `out_stride >= colour.width`, and returns the view of it
/// (empty when the input is empty or the stride too small). Allocates nothing.
inline ImageView to_grey(const ColourView& colour, std::uint8_t* out, int out_stride) {
  if (colour.empty() || out == nullptr || out_stride < colour.width) return {};
  for (int y = 0; y < colour.height; ++y) {
    const std::uint8_t* src = colour.pixel(0, y);
    std::uint8_t* dst = out + static_cast<long>(y) * out_stride;
    for (int x = 0; x < colour.width; ++x, src += ColourView::kChannels) dst[x] = grey_of(src[0], src[1], src[2]);
  }
  return ImageView{out, colour.width, colour.height, out_stride};
}

}  // namespace v4r::image
