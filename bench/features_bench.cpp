// v4r - robust model-based object tracking. MIT licence.
// Micro benchmarks of the oriented-window line tracker (paper 3.4: a fixed cost per feature).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "v4r/features/line_tracker.hpp"

namespace {

using v4r::features::LineMeasurement;
using v4r::features::LineTracker;
using v4r::features::LineTrackerParams;
using v4r::features::LineTrackState;
using v4r::features::Segment2;

constexpr int kWidth = 640, kHeight = 480;
constexpr double kAngle = 0.47;  // radians: edge direction in the image

/// \brief A 640x480 grey image holding one straight step edge through the centre (60 -> 180,
/// anti-aliased by 4x4 supersampling near the edge), optional clutter, Gaussian noise sigma 6.
struct EdgeImage {
  std::vector<std::uint8_t> px;
  Eigen::Vector2d centre{kWidth / 2.0 + 0.3, kHeight / 2.0 - 0.2};
  Eigen::Vector2d dir{std::cos(kAngle), std::sin(kAngle)};
  Eigen::Vector2d normal{-std::sin(kAngle), std::cos(kAngle)};

  explicit EdgeImage(bool clutter) : px(static_cast<std::size_t>(kWidth) * kHeight) {
    std::vector<float> f(px.size());
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x) {
        const double s = (Eigen::Vector2d(x, y) - centre).dot(normal);
        double cover;
        if (std::abs(s) > 1.0) {
          cover = s > 0 ? 1.0 : 0.0;
        } else {
          int in = 0;
          for (int k = 0; k < 16; ++k)
            in += (Eigen::Vector2d(x + (k % 4 + 0.5) / 4 - 0.5, y + (k / 4 + 0.5) / 4 - 0.5) - centre).dot(normal) > 0;
          cover = in / 16.0;
        }
        f[static_cast<std::size_t>(y) * kWidth + x] = static_cast<float>(60.0 + 120.0 * cover);
      }
    std::mt19937 rng(7);
    if (clutter) {
      // A weaker parallel edge 6 px away and bright blobs beside the edge.
      std::uniform_real_distribution<double> along(-80.0, 80.0), across(4.0, 12.0), side(0.0, 1.0);
      for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x)
          if ((Eigen::Vector2d(x, y) - centre).dot(normal) > 6.0) f[static_cast<std::size_t>(y) * kWidth + x] = 210.f;
      for (int b = 0; b < 30; ++b) {
        const Eigen::Vector2d c = centre + along(rng) * dir + (side(rng) < 0.5 ? -1.0 : 1.0) * across(rng) * normal;
        for (int y = static_cast<int>(c.y()) - 3; y <= static_cast<int>(c.y()) + 3; ++y)
          for (int x = static_cast<int>(c.x()) - 3; x <= static_cast<int>(c.x()) + 3; ++x)
            if ((Eigen::Vector2d(x, y) - c).norm() < 2.5) f[static_cast<std::size_t>(y) * kWidth + x] = 250.f;
      }
    }
    std::normal_distribution<double> noise(0.0, 6.0);
    for (std::size_t k = 0; k < px.size(); ++k)
      px[k] = static_cast<std::uint8_t>(std::clamp(std::lround(f[k] + noise(rng)), 0L, 255L));
  }

  [[nodiscard]] v4r::image::ImageView view() const { return {px.data(), kWidth, kHeight, kWidth}; }
  /// Prediction of the given length, 3 px off the edge and rotated by 3 degrees.
  [[nodiscard]] Segment2 prediction(double length) const {
    const double a = kAngle + 3.0 * 3.14159265358979 / 180.0;
    const Eigen::Vector2d d(std::cos(a), std::sin(a));
    const Eigen::Vector2d c = centre + 3.0 * normal;
    return {c - 0.5 * length * d, c + 0.5 * length * d};
  }
};

void run(benchmark::State& st, const EdgeImage& img, const LineTrackerParams& params, double length) {
  LineTracker tracker(params);
  const Segment2 pred = img.prediction(length);
  const v4r::image::ImageView view = img.view();
  int found = 0;
  for (auto _ : st) {
    LineTrackState state;
    const LineMeasurement m = tracker.track(view, pred, state);
    benchmark::DoNotOptimize(m);
    found += m.found ? 1 : 0;
  }
  if (found != static_cast<int>(st.iterations())) st.SkipWithError("edge not found");
  st.counters["rows"] = params.rows;
}

/// One 120-px window, default parameters (24 rows x 21 columns).
void BM_LineTrack(benchmark::State& st) {
  static const EdgeImage img(false);
  run(st, img, LineTrackerParams{}, 120.0);
}
BENCHMARK(BM_LineTrack);

/// A 400-px edge: same fixed window, so the same cost (subsampled along the edge).
void BM_LineTrackLongEdge(benchmark::State& st) {
  static const EdgeImage img(false);
  run(st, img, LineTrackerParams{}, 400.0);
}
BENCHMARK(BM_LineTrackLongEdge);

/// Parallel weaker edge and blobs: more edgels per row, the RANSAC sampler runs.
void BM_LineTrackClutter(benchmark::State& st) {
  static const EdgeImage img(true);
  run(st, img, LineTrackerParams{}, 120.0);
}
BENCHMARK(BM_LineTrackClutter);

/// Cost against the window height (rows) and the candidates kept per row.
void BM_LineTrackRowsCandidates(benchmark::State& st) {
  static const EdgeImage img(true);
  LineTrackerParams p;
  p.rows = static_cast<int>(st.range(0));
  p.max_candidates_per_row = static_cast<int>(st.range(1));
  run(st, img, p, 200.0);
}
BENCHMARK(BM_LineTrackRowsCandidates)->ArgsProduct({{12, 24, 48}, {3, 4}});

}  // namespace

