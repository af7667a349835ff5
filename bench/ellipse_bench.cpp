// v4r - robust model-based object tracking. MIT licence.
// Micro benchmarks of the elliptic-arc tracker (paper 3.2: a fixed cost per feature).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "v4r/features/ellipse_tracker.hpp"

namespace {

using v4r::features::CurveSample;
using v4r::features::EllipseMeasurement;
using v4r::features::EllipseTracker;
using v4r::features::EllipseTrackerParams;
using v4r::features::EllipseTrackState;

constexpr int kWidth = 640, kHeight = 480;
constexpr double kPi = 3.14159265358979323846;

/// \brief Ellipse (centre, semi-axes a, b in pixels, angle of a in radians) with point/normal sampling.
struct Shape {
  double cx, cy, a, b, angle;
  [[nodiscard]] double rho(double x, double y) const {
    const double dx = x - cx, dy = y - cy, cs = std::cos(angle), sn = std::sin(angle);
    const double u = cs * dx + sn * dy, v = -sn * dx + cs * dy;
    return std::hypot(u / a, v / b);
  }
  /// n samples with outward unit normals over the parametric angles [t0, t0 + span).
  [[nodiscard]] std::vector<CurveSample> samples(int n, double t0 = 0.0, double span = 2.0 * kPi) const {
    std::vector<CurveSample> out;
    const double cs = std::cos(angle), sn = std::sin(angle);
    for (int i = 0; i < n; ++i) {
      const double t = t0 + span * i / n;
      const double x = a * std::cos(t), y = b * std::sin(t);
      const double nx = b * std::cos(t), ny = a * std::sin(t);
      CurveSample s;
      s.p = {cx + cs * x - sn * y, cy + sn * x + cs * y};
      s.normal = Eigen::Vector2d(cs * nx - sn * ny, sn * nx + cs * ny).normalized();
      out.push_back(s);
    }
    return out;
  }
};

/// The true ellipse of the benchmark image; predictions are perturbed copies.
constexpr Shape kTruth{321.3, 238.6, 120.0, 80.0, 0.4};

/// \brief A 640x480 grey image of one filled ellipse (170 on 60, anti-aliased by 4x4
/// supersampling near the edge), optional clutter (crossing bright lines, dark blobs), noise sigma 5.
struct EllipseImage {
  std::vector<std::uint8_t> px;

  explicit EllipseImage(bool clutter) : px(static_cast<std::size_t>(kWidth) * kHeight) {
    std::vector<float> f(px.size(), 60.f);
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x) {
        const double r = kTruth.rho(x, y);
        double cover;
        if ((r - 1.0) * kTruth.b > 1.0) {
          cover = 0.0;
        } else if ((1.0 - r) * kTruth.b > 1.0) {
          cover = 1.0;
        } else {
          int in = 0;
          for (int k = 0; k < 16; ++k) in += kTruth.rho(x + (k % 4 + 0.5) / 4 - 0.5, y + (k / 4 + 0.5) / 4 - 0.5) < 1.0;
          cover = in / 16.0;
        }
        f[static_cast<std::size_t>(y) * kWidth + x] = static_cast<float>(60.0 + 110.0 * cover);
      }
    std::mt19937 rng(11);
    if (clutter) {
      std::uniform_real_distribution<double> u01(0.0, 1.0);
      for (int k = 0; k < 4; ++k) {  // bright straight lines, 3 px wide, through the ellipse
        const double phi = kPi * u01(rng), off = 60.0 * (2.0 * u01(rng) - 1.0);
        const double nx = -std::sin(phi), ny = std::cos(phi);
        for (int y = 0; y < kHeight; ++y)
          for (int x = 0; x < kWidth; ++x)
            if (std::abs((x - kTruth.cx) * nx + (y - kTruth.cy) * ny - off) < 1.5)
              f[static_cast<std::size_t>(y) * kWidth + x] = 230.f;
      }
      for (int k = 0; k < 25; ++k) {  // dark blobs near the edge
        const double t = 2.0 * kPi * u01(rng), s = 1.0 + 0.12 * (2.0 * u01(rng) - 1.0);
        const double cs = std::cos(kTruth.angle), sn = std::sin(kTruth.angle);
        const double ex = s * kTruth.a * std::cos(t), ey = s * kTruth.b * std::sin(t);
        const double bx = kTruth.cx + cs * ex - sn * ey, by = kTruth.cy + sn * ex + cs * ey;
        for (int y = static_cast<int>(by) - 5; y <= static_cast<int>(by) + 5; ++y)
          for (int x = static_cast<int>(bx) - 5; x <= static_cast<int>(bx) + 5; ++x)
            if (x >= 0 && y >= 0 && x < kWidth && y < kHeight && std::hypot(x - bx, y - by) < 4.0)
              f[static_cast<std::size_t>(y) * kWidth + x] = 20.f;
      }
    }
    std::normal_distribution<double> noise(0.0, 5.0);
    for (std::size_t k = 0; k < px.size(); ++k)
      px[k] = static_cast<std::uint8_t>(std::clamp(std::lround(f[k] + noise(rng)), 0L, 255L));
  }

  [[nodiscard]] v4r::image::ImageView view() const { return {px.data(), kWidth, kHeight, kWidth}; }
};

/// Prediction: 3 px off, axes scaled by 1.03 / 0.98, rotated by 2 degrees.
Shape prediction() {
  return Shape{kTruth.cx + 2.4, kTruth.cy - 1.8, kTruth.a * 1.03, kTruth.b * 0.98, kTruth.angle + 2.0 * kPi / 180.0};
}

void run(benchmark::State& st, const EllipseImage& img, const EllipseTrackerParams& params,
         const std::vector<CurveSample>& samples) {
  EllipseTracker tracker(params);
  const v4r::image::ImageView view = img.view();
  int found = 0;
  for (auto _ : st) {
    EllipseTrackState state;
    const EllipseMeasurement m = tracker.track(view, samples, state);
    benchmark::DoNotOptimize(m);
    found += m.found ? 1 : 0;
  }
  if (found != static_cast<int>(st.iterations())) st.SkipWithError("ellipse not found");
  st.counters["samples"] = static_cast<double>(std::min<std::size_t>(samples.size(), params.max_samples));
}

/// 32 samples around the ellipse, default parameters (search +-8 px).
void BM_EllipseTrack32(benchmark::State& st) {
  static const EllipseImage img(false);
  run(st, img, EllipseTrackerParams{}, prediction().samples(32));
}
BENCHMARK(BM_EllipseTrack32);

/// 32 samples over half of the ellipse.
void BM_EllipseTrackHalfArc32(benchmark::State& st) {
  static const EllipseImage img(false);
  run(st, img, EllipseTrackerParams{}, prediction().samples(32, 0.5, kPi));
}
BENCHMARK(BM_EllipseTrackHalfArc32);

/// Crossing lines and blobs: more candidates per line, RANSAC runs its full budget.
void BM_EllipseTrackClutter32(benchmark::State& st) {
  static const EllipseImage img(true);
  run(st, img, EllipseTrackerParams{}, prediction().samples(32));
}
BENCHMARK(BM_EllipseTrackClutter32);

/// 400 predicted samples: subsampled to max_samples (48), so the cost stays fixed.
void BM_EllipseTrackSubsampled400(benchmark::State& st) {
  static const EllipseImage img(false);
  run(st, img, EllipseTrackerParams{}, prediction().samples(400));
}
BENCHMARK(BM_EllipseTrackSubsampled400);

/// Cost against the number of samples and the search half-length (pixels).
void BM_EllipseTrackSamplesHalfLength(benchmark::State& st) {
  static const EllipseImage img(true);
  EllipseTrackerParams p;
  p.max_samples = static_cast<int>(st.range(0));
  p.half_length = static_cast<int>(st.range(1));
  run(st, img, p, prediction().samples(static_cast<int>(st.range(0))));
}
BENCHMARK(BM_EllipseTrackSamplesHalfLength)->ArgsProduct({{16, 32, 48}, {8, 16}});

}  // namespace
