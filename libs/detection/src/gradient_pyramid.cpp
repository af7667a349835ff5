// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/gradient_pyramid.hpp"

#include <algorithm>
#include <cmath>

namespace v4r::detection {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kHistBins = 4096;  // Sobel |gx| + |gy| of 8-bit images stays below 4 * 255 * 2

/// One row of the Sobel gradient of an interleaved image with CH channels, the channel of largest
/// magnitude per pixel (the first of equal ones), for x in [xa, xb). Branch-free, so that the
/// compiler vectorises it with CH known.
template <int CH>
void sobel_max_row(const std::uint8_t* r0, const std::uint8_t* r1, const std::uint8_t* r2, int xa, int xb,
                   std::int16_t* ox, std::int16_t* oy) {
  for (int x = xa; x < xb; ++x) {
    int bx = 0, by = 0, best = -1;
    for (int c = 0; c < CH; ++c) {
      const int l = (x - 1) * CH + c, m = x * CH + c, r = (x + 1) * CH + c;
      const int dx = (r0[r] - r0[l]) + 2 * (r1[r] - r1[l]) + (r2[r] - r2[l]);
      const int dy = (r2[l] - r0[l]) + 2 * (r2[m] - r0[m]) + (r2[r] - r0[r]);
      const int m2 = dx * dx + dy * dy;
      const bool more = m2 > best;
      bx = more ? dx : bx;
      by = more ? dy : by;
      best = more ? m2 : best;
    }
    ox[x] = static_cast<std::int16_t>(bx);
    oy[x] = static_cast<std::int16_t>(by);
  }
}

/// Sobel gradient of an interleaved image (w x h, `ch` = 1 or 3 channels), the channel of largest
/// magnitude per pixel, at the pixels of `b` (clipped to the image's interior); output rows are
/// w values apart. Image border pixels get 0; pixels outside `b` are not written.
void sobel_max(const std::uint8_t* data, int stride, int ch, int w, int h, PixelBox b, std::int16_t* gx, std::int16_t* gy) {
  if (b.y0 == 0 || b.y1 == h)
    for (int x = b.x0; x < b.x1; ++x) {
      if (b.y0 == 0) gx[x] = gy[x] = 0;
      if (b.y1 == h) gx[static_cast<std::size_t>(h - 1) * w + x] = gy[static_cast<std::size_t>(h - 1) * w + x] = 0;
    }
  const int xa = std::max(1, b.x0), xb = std::min(w - 1, b.x1);
  for (int y = std::max(1, b.y0); y < std::min(h - 1, b.y1); ++y) {
    const std::uint8_t* r0 = data + static_cast<long>(y - 1) * stride;
    const std::uint8_t* r1 = r0 + stride;
    const std::uint8_t* r2 = r1 + stride;
    std::int16_t* ox = gx + static_cast<std::size_t>(y) * w;
    std::int16_t* oy = gy + static_cast<std::size_t>(y) * w;
    if (b.x0 == 0) ox[0] = oy[0] = 0;
    if (b.x1 == w) ox[w - 1] = oy[w - 1] = 0;
    if (ch == 1)
      sobel_max_row<1>(r0, r1, r2, xa, xb, ox, oy);
    else
      sobel_max_row<3>(r0, r1, r2, xa, xb, ox, oy);
  }
}

/// 2x2 mean of an interleaved image into a dense one of size w2 x h2, at the pixels of `b`
/// (output pixels).
void halve(const std::uint8_t* src, int stride, int ch, int w2, PixelBox b, std::uint8_t* dst) {
  for (int y = b.y0; y < b.y1; ++y) {
    const std::uint8_t* a = src + static_cast<long>(2 * y) * stride;
    const std::uint8_t* bb = a + stride;
    std::uint8_t* o = dst + static_cast<std::size_t>(y) * w2 * ch;
    for (int x = b.x0; x < b.x1; ++x)
      for (int c = 0; c < ch; ++c) {
        const int i = 2 * x * ch + c;
        o[x * ch + c] = static_cast<std::uint8_t>((a[i] + a[i + ch] + bb[i] + bb[i + ch] + 2) >> 2);
      }
  }
}

/// `b` divided by `f` (outward) and grown by `grow`, clipped to w x h.
PixelBox scaled(PixelBox b, int f, int grow, int w, int h) {
  return PixelBox{std::max(0, b.x0 / f - grow), std::max(0, b.y0 / f - grow), std::min(w, (b.x1 + f - 1) / f + grow),
                  std::min(h, (b.y1 + f - 1) / f + grow)};
}

void allocate(OrientationLevel& l, int w, int h, int spread, bool linear) {
  l.width = w;
  l.height = h;
  l.spread = spread;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  l.image.assign(n * 3, 0);
  l.bits.assign(n, 0);
  l.spread_bits.assign(n, 0);
  for (auto& r : l.response) r.assign(n + kResponsePadding, 0);
  l.lin_width = (w + 1) / 2;
  l.lin_height = (h + 1) / 2;
  if (linear)
    for (auto& o : l.linear)
      for (auto& ph : o) ph.assign(static_cast<std::size_t>(l.lin_width) * l.lin_height + kLinearPadding, 0);
}

/// lut[o][mask]: best similarity of orientation o to the orientations set in mask.
struct SimilarityLut {
  std::uint8_t v[kOrientations][256];
  SimilarityLut() {
    for (int o = 0; o < kOrientations; ++o)
      for (int m = 0; m < 256; ++m) {
        int best = 0;
        for (int b = 0; b < kOrientations; ++b)
          if (m & (1 << b)) best = std::max(best, orientation_similarity(o, b));
        v[o][m] = static_cast<std::uint8_t>(best);
      }
  }
};
const SimilarityLut& lut() {
  static const SimilarityLut l;
  return l;
}

}  // namespace

int quantise_orientation(double x, double y) {
  double a = std::atan2(y, x);
  if (a < 0) a += kPi;
  int b = static_cast<int>(a * (kOrientations / kPi));
  if (b >= kOrientations) b -= kOrientations;
  return b < 0 ? 0 : b;
}

int quantise_gradient_orientation(int gx, int gy) {
  static_assert(kOrientations == 8, "the boundaries below are those of 8 bins");
  if (gy < 0 || (gy == 0 && gx < 0)) {
    gx = -gx;
    gy = -gy;
  }
  // Angle a in [0, 180) deg reaches boundary k * 22.5 deg when sin(a - k * 22.5 deg) >= 0:
  // cos_k gy - sin_k gx >= 0. The boundaries at 45, 90 and 135 deg in integers (exact ties).
  // cos and sin of 22.5 deg (the sin and cos of 67.5 deg).
  constexpr double c = 0.92387953251128674, s = 0.38268343236508978;
  const double x = gx, y = gy;
  int b = 0;
  b += c * y - s * x >= 0.0 ? 1 : 0;   // 22.5 deg
  b += gy >= gx ? 1 : 0;               // 45
  b += s * y - c * x >= 0.0 ? 1 : 0;   // 67.5
  b += gx <= 0 ? 1 : 0;                // 90
  b += -s * y - c * x >= 0.0 ? 1 : 0;  // 112.5
  b += gx + gy <= 0 ? 1 : 0;           // 135
  b += -c * y - s * x >= 0.0 ? 1 : 0;  // 157.5
  return b;
}

int orientation_similarity(int a, int b) {
  int d = std::abs(a - b);
  d = std::min(d, kOrientations - d);
  return d == 0 ? 4 : (d == 1 ? 1 : 0);
}

GradientPyramid::GradientPyramid(int width, int height, int fine_spread, int coarse_spread)
    : width_(std::max(width, 8)), height_(std::max(height, 8)) {
  const std::size_t n = static_cast<std::size_t>(width_) * height_;
  gx_.assign(n, 0);
  gy_.assign(n, 0);
  lgx_.assign(n / 4 + 1, 0);
  lgy_.assign(n / 4 + 1, 0);
  allocate(fine_, width_ / 2, height_ / 2, fine_spread, false);
  allocate(coarse_, width_ / 4, height_ / 4, coarse_spread, true);
  hist_.assign(kHistBins, 0);
}

int GradientPyramid::median_l1(const std::int16_t* gx, const std::int16_t* gy, int w, PixelBox b) {
  std::fill(hist_.begin(), hist_.end(), 0);
  long n = 0;
  for (int y = b.y0; y < b.y1; ++y) {
    const std::int16_t* ox = gx + static_cast<std::size_t>(y) * w;
    const std::int16_t* oy = gy + static_cast<std::size_t>(y) * w;
    for (int x = b.x0; x < b.x1; ++x) ++hist_[static_cast<std::size_t>(std::min(kHistBins - 1, std::abs(ox[x]) + std::abs(oy[x])))];
    n += std::max(0, b.x1 - b.x0);
  }
  long acc = 0;
  for (int i = 0; i < kHistBins; ++i) {
    acc += hist_[static_cast<std::size_t>(i)];
    if (2 * acc >= n) return i;
  }
  return kHistBins - 1;
}

bool GradientPyramid::compute(const image::ImageView& grey, const GradientThreshold& t) {
  if (grey.empty() || grey.width != width_ || grey.height != height_) return false;
  return compute_from(grey.data, grey.stride, 1, t, PixelBox{0, 0, width_, height_});
}

bool GradientPyramid::compute(const image::ColourView& bgr, const GradientThreshold& t) {
  if (bgr.empty() || bgr.width != width_ || bgr.height != height_) return false;
  return compute_from(bgr.data, bgr.stride, 3, t, PixelBox{0, 0, width_, height_});
}

bool GradientPyramid::compute(const image::ColourView& bgr, const GradientThreshold& t, PixelBox roi) {
  if (bgr.empty() || bgr.width != width_ || bgr.height != height_) return false;
  // Multiples of 4, so that the levels' pixels inside are whole.
  roi = PixelBox{std::max(0, roi.x0 & ~3), std::max(0, roi.y0 & ~3), std::min(width_, (roi.x1 + 3) & ~3),
                 std::min(height_, (roi.y1 + 3) & ~3)};
  if (roi.empty()) roi = PixelBox{0, 0, 4, 4};
  return compute_from(bgr.data, bgr.stride, 3, t, roi);
}

void GradientPyramid::clear() {
  std::fill(gx_.begin(), gx_.end(), 0);
  std::fill(gy_.begin(), gy_.end(), 0);
  for (OrientationLevel* l : {&fine_, &coarse_}) {
    std::fill(l->bits.begin(), l->bits.end(), 0);
    std::fill(l->spread_bits.begin(), l->spread_bits.end(), 0);
    for (auto& r : l->response) std::fill(r.begin(), r.end(), 0);
    for (auto& o : l->linear)
      for (auto& ph : o) std::fill(ph.begin(), ph.end(), 0);
  }
}

bool GradientPyramid::compute_from(const std::uint8_t* data, int stride, int ch, const GradientThreshold& t, PixelBox roi) {
  const bool whole = roi.x0 == 0 && roi.y0 == 0 && roi.x1 == width_ && roi.y1 == height_;
  if (!whole) clear();
  sobel_max(data, stride, ch, width_, height_, roi, gx_.data(), gy_.data());
  noise_ = median_l1(gx_.data(), gy_.data(), width_, roi) / 8.0;  // Sobel is 8x the gradient
  // Each level's box (level pixels) inside the roi; the level images wider for the level's Sobel
  // (1 pixel) and the next halving (2 fine pixels per coarse one).
  const PixelBox fb = scaled(roi, 2, 0, fine_.width, fine_.height), cb = scaled(roi, 4, 0, coarse_.width, coarse_.height);
  halve(data, stride, ch, fine_.width, scaled(roi, 2, 2, fine_.width, fine_.height), fine_.image.data());
  halve(fine_.image.data(), fine_.width * ch, ch, coarse_.width, scaled(roi, 4, 1, coarse_.width, coarse_.height),
        coarse_.image.data());
  orientations(fine_, ch, t, false, fb);
  orientations(coarse_, ch, t, true, cb);
  return true;
}

void GradientPyramid::orientations(OrientationLevel& l, int ch, const GradientThreshold& thr, bool linear, PixelBox b) {
  const int w = l.width, h = l.height;
  sobel_max(l.image.data(), w * ch, ch, w, h, b, lgx_.data(), lgy_.data());
  // Sobel is 8x the gradient per pixel.
  l.noise = median_l1(lgx_.data(), lgy_.data(), w, b) / 8.0;
  l.threshold = thr.at(l.noise);
  const double t = 8.0 * l.threshold;
  const std::int64_t t2 = static_cast<std::int64_t>(t * t);
  // Orientation boundaries: bin k covers angles [k, k+1) * pi / 8 in the upper half plane.
  for (int y = b.y0; y < b.y1; ++y)
    for (std::size_t i = static_cast<std::size_t>(y) * w + b.x0, e = static_cast<std::size_t>(y) * w + b.x1; i < e; ++i) {
      int dx = lgx_[i], dy = lgy_[i];
      const std::int64_t m2 = static_cast<std::int64_t>(dx) * dx + static_cast<std::int64_t>(dy) * dy;
      if (m2 <= t2 || m2 == 0) {
        l.bits[i] = 0;
        continue;
      }
      l.bits[i] = static_cast<std::uint8_t>(1u << quantise_gradient_orientation(dx, dy));
    }
  // Spread: OR over (2r+1)^2, separably (rows into spread_bits, then columns in place via a row),
  // over the box grown by r (outside the box the bits are 0).
  const int r = l.spread;
  const PixelBox g{std::max(0, b.x0 - r), std::max(0, b.y0 - r), std::min(w, b.x1 + r), std::min(h, b.y1 + r)};
  for (int y = g.y0; y < g.y1; ++y) {
    const std::uint8_t* src = l.bits.data() + static_cast<std::size_t>(y) * w;
    std::uint8_t* dst = l.spread_bits.data() + static_cast<std::size_t>(y) * w;
    for (int x = g.x0; x < g.x1; ++x) {
      std::uint8_t m = 0;
      for (int k = std::max(0, x - r); k <= std::min(w - 1, x + r); ++k) m |= src[k];
      dst[x] = m;
    }
  }
  // Columns: write into bits (no longer needed) and swap roles by copying back.
  for (int y = g.y0; y < g.y1; ++y) {
    std::uint8_t* dst = l.bits.data() + static_cast<std::size_t>(y) * w;
    const int y0 = std::max(g.y0, y - r), y1 = std::min(g.y1 - 1, y + r);
    for (int x = g.x0; x < g.x1; ++x) dst[x] = 0;
    for (int yy = y0; yy <= y1; ++yy) {
      const std::uint8_t* src = l.spread_bits.data() + static_cast<std::size_t>(yy) * w;
      for (int x = g.x0; x < g.x1; ++x) dst[x] |= src[x];
    }
  }
  for (int y = g.y0; y < g.y1; ++y) {
    const std::size_t i0 = static_cast<std::size_t>(y) * w;
    std::copy(l.bits.begin() + static_cast<std::ptrdiff_t>(i0 + g.x0), l.bits.begin() + static_cast<std::ptrdiff_t>(i0 + g.x1),
              l.spread_bits.begin() + static_cast<std::ptrdiff_t>(i0 + g.x0));
  }
  const SimilarityLut& L = lut();
  for (int o = 0; o < kOrientations; ++o) {
    std::uint8_t* resp = l.response[o].data();
    const std::uint8_t* tab = L.v[o];
    for (int y = g.y0; y < g.y1; ++y)
      for (std::size_t i = static_cast<std::size_t>(y) * w + g.x0, e = static_cast<std::size_t>(y) * w + g.x1; i < e; ++i)
        resp[i] = tab[l.spread_bits[i]];
    if (!linear) continue;
    for (int py = 0; py < 2; ++py)
      for (int px = 0; px < 2; ++px) {
        std::uint8_t* lin = l.linear[o][py * 2 + px].data();
        for (int j = 0; j < l.lin_height; ++j) {
          const int y = 2 * j + py;
          std::uint8_t* row = lin + static_cast<std::size_t>(j) * l.lin_width;
          if (y >= h) {
            std::fill(row, row + l.lin_width, 0);
            continue;
          }
          const std::uint8_t* src = resp + static_cast<std::size_t>(y) * w;
          for (int i = 0; i < l.lin_width; ++i) {
            const int x = 2 * i + px;
            row[i] = x < w ? src[x] : 0;
          }
        }
      }
  }
}

}  // namespace v4r::detection
