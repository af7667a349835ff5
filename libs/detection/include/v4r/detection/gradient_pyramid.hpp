// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "v4r/image/colour_view.hpp"
#include "v4r/image/image_view.hpp"

namespace v4r::detection {

/// Number of quantised gradient orientations over 180 degrees (polarity is ignored).
inline constexpr int kOrientations = 8;

/// Quantised orientation (0 .. kOrientations-1) of a direction (x, y), modulo 180 degrees:
/// bin k covers [k, k+1) * 180 / kOrientations degrees.
int quantise_orientation(double x, double y);
/// The same for an integer gradient (Sobel responses, |gx|, |gy| <= 4 x 255), without atan2: the
/// direction is folded into the upper half plane and counted against the seven bin boundaries.
/// Equal to quantise_orientation(gx, gy) for every such gradient, ties on a boundary included.
int quantise_gradient_orientation(int gx, int gy);

/// Similarity of two quantised orientations as the response maps score it: 4 when equal, 1 when
/// neighbours (22.5 degrees apart), else 0.
int orientation_similarity(int a, int b);

/// Zero bytes after each response map: block reads from a row's last pixels stay inside it.
inline constexpr int kResponsePadding = 16;
/// Zero bytes after each of the coarse level's linear maps, for the same reason.
inline constexpr int kLinearPadding = 32;

/// \brief One level of the orientation pyramid: quantised orientations, their spread over a
/// square neighbourhood and the response map per orientation (uint8 per pixel, the best
/// similarity of the template orientation to any orientation spread onto that pixel).
struct OrientationLevel {
  int width = 0, height = 0;
  int spread = 0;  ///< px
  std::vector<std::uint8_t> image;   ///< this level's pixels (1 or 3 channels, interleaved)
  std::vector<std::uint8_t> bits;    ///< per pixel: 1 << orientation, 0 when the gradient is weak
  std::vector<std::uint8_t> spread_bits;
  /// width * height each, then kResponsePadding zeros (a matcher may read a block of
  /// kResponsePadding bytes from any pixel)
  std::array<std::vector<std::uint8_t>, kOrientations> response;
  /// Response maps split into the four 2x2 phases (stride-2 evaluation with contiguous rows):
  /// Only at the coarse level: linear[o][py * 2 + px] has lin_width x lin_height pixels, entry (i, j) = response (2i+px, 2j+py),
  /// then kLinearPadding zeros.
  std::array<std::array<std::vector<std::uint8_t>, 4>, kOrientations> linear;
  int lin_width = 0, lin_height = 0;
  double noise = 0.0;      ///< grey levels per level pixel: median of |gx| + |gy| over the computed box
  double threshold = 0.0;  ///< grey levels per level pixel: weakest gradient given an orientation
};

/// \brief The gradient threshold of a frame, relative to its noise (and texture): a gradient
/// carries an edge when it exceeds max(floor, min(ceiling, factor * noise)), `noise` being the
/// median of |gx| + |gy| (grey levels per pixel) over the image. Clean images (blur lowers their
/// edges' gradients) get the floor, noisy ones up to the ceiling. factor 0: the ceiling always.
struct GradientThreshold {
  double ceiling = 8.0;  ///< grey/px
  double floor = 3.0;    ///< grey/px
  double factor = 1.5;
  [[nodiscard]] double at(double noise) const {
    return factor <= 0.0 ? ceiling : std::max(std::min(floor, ceiling), std::min(ceiling, factor * noise));
  }
};

/// \brief A rectangle of full-resolution pixels [x0, x1) x [y0, y1).
struct PixelBox {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  [[nodiscard]] bool empty() const { return x1 <= x0 || y1 <= y0; }
};

/// \brief The image side of detection, computed once per frame into buffers sized at
/// construction (no allocation per frame): Sobel gradients at full resolution (of the channel
/// with the largest gradient for colour input) for refinement and verification, and orientation
/// levels at 1/2 and 1/4 resolution for the template search.
class GradientPyramid {
 public:
  GradientPyramid(int width, int height, int fine_spread, int coarse_spread);

  /// Computes everything for a grey or BGR image of the constructor's size; each level's
  /// orientations with `t` at that level's noise (OrientationLevel::noise, ::threshold).
  /// Returns false (and computes nothing) when the size differs.
  bool compute(const image::ImageView& grey, const GradientThreshold& t);
  bool compute(const image::ColourView& bgr, const GradientThreshold& t);
  /// The same inside `roi` only (widened to multiples of 4 and clipped to the image); every
  /// gradient, orientation and response outside it is 0 (the colour stage's windows).
  bool compute(const image::ColourView& bgr, const GradientThreshold& t, PixelBox roi);

  [[nodiscard]] int width() const { return width_; }
  [[nodiscard]] int height() const { return height_; }
  /// Full-resolution Sobel gradient (8x the gradient in grey levels per pixel).
  [[nodiscard]] std::int16_t gx(int x, int y) const { return gx_[static_cast<std::size_t>(y) * width_ + x]; }
  [[nodiscard]] std::int16_t gy(int x, int y) const { return gy_[static_cast<std::size_t>(y) * width_ + x]; }
  /// Median of |gx| + |gy| of the full-resolution gradients (grey levels per pixel) over the
  /// computed box: the frame's noise and texture level.
  [[nodiscard]] double noise() const { return noise_; }
  [[nodiscard]] const OrientationLevel& fine() const { return fine_; }      ///< 1/2 resolution
  [[nodiscard]] const OrientationLevel& coarse() const { return coarse_; }  ///< 1/4 resolution

 private:
  bool compute_from(const std::uint8_t* data, int stride, int channels, const GradientThreshold& t, PixelBox roi);
  /// Orientations, spread and responses of `level` inside `b` (level pixels).
  void orientations(OrientationLevel& level, int channels, const GradientThreshold& t, bool linear, PixelBox b);
  /// Median of |gx| + |gy| (Sobel units) over box `b` of gradients w values apart per row.
  int median_l1(const std::int16_t* gx, const std::int16_t* gy, int w, PixelBox b);
  void clear();  // zeroes every gradient, orientation and response

  int width_, height_;
  std::vector<std::int16_t> gx_, gy_;
  std::vector<std::int16_t> lgx_, lgy_;  // scratch for the levels
  OrientationLevel fine_, coarse_;
  double noise_ = 0.0;
  std::vector<int> hist_;  // median_l1's histogram
};

}  // namespace v4r::detection
