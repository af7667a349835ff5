// v4r - robust model-based object tracking. MIT licence.
// Synthetic test images for the feature trackers: anti-aliased shapes (8x8 supersampled coverage)
// painted into grey or B, G, R float images, quantized to 8 bits with Gaussian noise.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <Eigen/Core>

#include "v4r/features/line_tracker.hpp"
#include "v4r/image/colour_view.hpp"
#include "v4r/image/image_view.hpp"

namespace v4r::features::test_images {

constexpr double kPi = 3.14159265358979323846;

/// \brief A colour in B, G, R order (grey levels 0..255, float).
struct Bgr {
  float b = 0.0f, g = 0.0f, r = 0.0f;
  [[nodiscard]] Bgr scaled(float f) const { return {b * f, g * f, r * f}; }
  /// BT.601 luma, the grey level image::grey_of gives (before rounding).
  [[nodiscard]] float grey() const { return 0.114f * b + 0.587f * g + 0.299f * r; }
};

/// \brief Float image (1 grey or 3 B, G, R channels) painted with anti-aliased shapes, then
/// quantized to 8 bits with Gaussian noise.
class Canvas {
 public:
  Canvas(int width, int height, float fill) : w_(width), h_(height), c_(1), px_(size(), fill) {}
  Canvas(int width, int height, const Bgr& fill) : w_(width), h_(height), c_(3), px_(size() * 3) {
    for (std::size_t k = 0; k < px_.size(); k += 3) {
      px_[k] = fill.b;
      px_[k + 1] = fill.g;
      px_[k + 2] = fill.r;
    }
  }

  /// Paints `value` (float on grey, Bgr on colour canvases) where the signed distance
  /// `sdf(x, y)` (pixels, negative inside, 1-Lipschitz) is negative, blending each pixel by its
  /// coverage.
  template <typename Sdf>
  void paint(const Sdf& sdf, float value) {
    const float v[3] = {value, value, value};
    paint_values(sdf, v);
  }
  template <typename Sdf>
  void paint(const Sdf& sdf, const Bgr& value) {
    const float v[3] = {value.b, value.g, value.r};
    paint_values(sdf, v);
  }

  /// Half-plane of points x with (x - p0) . normal > 0.
  template <typename V>
  void half_plane(const Eigen::Vector2d& p0, const Eigen::Vector2d& normal, const V& value) {
    const Eigen::Vector2d nn = normal.normalized();
    paint([&](double x, double y) { return -((x - p0.x()) * nn.x() + (y - p0.y()) * nn.y()); }, value);
  }
  template <typename V>
  void disc(const Eigen::Vector2d& c, double r, const V& value) {
    paint([&](double x, double y) { return std::hypot(x - c.x(), y - c.y()) - r; }, value);
  }
  /// Thick segment p-q of radius r (a short bright or dark line).
  template <typename V>
  void capsule(const Eigen::Vector2d& p, const Eigen::Vector2d& q, double r, const V& value) {
    const Eigen::Vector2d pq = q - p;
    const double l2 = pq.squaredNorm();
    paint(
        [&](double x, double y) {
          const Eigen::Vector2d xp(x - p.x(), y - p.y());
          const double t = std::clamp(xp.dot(pq) / l2, 0.0, 1.0);
          return (xp - t * pq).norm() - r;
        },
        value);
  }

  /// 8-bit image (channels interleaved) with additive Gaussian noise per sample (fixed seed).
  [[nodiscard]] std::vector<std::uint8_t> quantize(double sigma, std::uint32_t seed) const {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, sigma);
    std::vector<std::uint8_t> out(px_.size());
    for (std::size_t k = 0; k < px_.size(); ++k) {
      const double v = px_[k] + (sigma > 0.0 ? noise(rng) : 0.0);
      out[k] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
    }
    return out;
  }

  [[nodiscard]] int width() const { return w_; }
  [[nodiscard]] int height() const { return h_; }
  [[nodiscard]] int channels() const { return c_; }

 private:
  [[nodiscard]] std::size_t size() const { return static_cast<std::size_t>(w_) * static_cast<std::size_t>(h_); }

  template <typename Sdf>
  void paint_values(const Sdf& sdf, const float* v) {
    constexpr int kSub = 8;
    for (int y = 0; y < h_; ++y) {
      for (int x = 0; x < w_; ++x) {
        const double d0 = sdf(static_cast<double>(x), static_cast<double>(y));
        double cover;
        if (d0 <= -0.75) {
          cover = 1.0;
        } else if (d0 >= 0.75) {
          continue;
        } else {
          int in = 0;
          for (int sy = 0; sy < kSub; ++sy)
            for (int sx = 0; sx < kSub; ++sx)
              if (sdf(x + (sx + 0.5) / kSub - 0.5, y + (sy + 0.5) / kSub - 0.5) < 0.0) ++in;
          cover = static_cast<double>(in) / (kSub * kSub);
        }
        float* p = &px_[(static_cast<std::size_t>(y) * w_ + x) * c_];
        for (int c = 0; c < c_; ++c) p[c] = static_cast<float>(p[c] * (1.0 - cover) + v[c] * cover);
      }
    }
  }

  int w_, h_, c_;
  std::vector<float> px_;
};

inline image::ImageView view_of(const std::vector<std::uint8_t>& buf, int w, int h) {
  image::ImageView v;
  v.data = buf.data();
  v.width = w;
  v.height = h;
  v.stride = w;
  return v;
}

inline image::ColourView colour_view_of(const std::vector<std::uint8_t>& buf, int w, int h) {
  image::ColourView v;
  v.data = buf.data();
  v.width = w;
  v.height = h;
  v.stride = 3 * w;
  return v;
}

/// \brief A quantized colour frame and its grey conversion (image::to_grey), as a camera
/// pipeline would hand them to the tracker.
struct ColourFrame {
  int width = 0, height = 0;
  std::vector<std::uint8_t> bgr, grey;
  ColourFrame(const Canvas& canvas, double sigma, std::uint32_t seed)
      : width(canvas.width()), height(canvas.height()), bgr(canvas.quantize(sigma, seed)),
        grey(static_cast<std::size_t>(width) * height) {
    (void)image::to_grey(colour(), grey.data(), width);
  }
  [[nodiscard]] image::ColourView colour() const { return colour_view_of(bgr, width, height); }
  [[nodiscard]] image::ImageView grey_view() const { return view_of(grey, width, height); }
};

/// \brief Ground-truth infinite line through p with unit direction t.
struct TrueLine {
  Eigen::Vector2d p;
  Eigen::Vector2d t;
  [[nodiscard]] Eigen::Vector2d normal() const { return {-t.y(), t.x()}; }
  [[nodiscard]] double distance(const Eigen::Vector2d& x) const { return std::abs((x - p).dot(normal())); }
  /// Largest distance of the measured line's two points from this line (pixels).
  [[nodiscard]] double error(const Segment2& s) const { return std::max(distance(s.a), distance(s.b)); }
};

inline Eigen::Vector2d dir(double angle) { return {std::cos(angle), std::sin(angle)}; }

inline Segment2 segment(const Eigen::Vector2d& centre, const Eigen::Vector2d& t, double length) {
  return {centre - 0.5 * length * t, centre + 0.5 * length * t};
}

/// Step edge along `line`: `dark` on the -normal side, `bright` on the +normal side.
inline Canvas step_edge(int w, int h, const TrueLine& line, float dark, float bright) {
  Canvas c(w, h, dark);
  c.half_plane(line.p, line.normal(), bright);
  return c;
}

/// \brief Running mean and maximum of an error.
struct ErrorStats {
  double sum = 0.0, max = 0.0;
  int n = 0;
  void add(double e) {
    sum += e;
    max = std::max(max, e);
    ++n;
  }
  [[nodiscard]] double mean() const { return n > 0 ? sum / n : 0.0; }
};

}  // namespace v4r::features::test_images
