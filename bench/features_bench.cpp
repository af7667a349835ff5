// v4r - robust model-based object tracking. MIT licence.
// Micro benchmarks of the oriented-window line tracker (paper 3.4: a fixed cost per feature).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "v4r/features/line_tracker.hpp"
#include "v4r/image/colour_view.hpp"

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

// ---------------------------------------------------------------------------------------------
// Cue integration (paper 4.1): cost of the appearance check of a learned object side.

/// \brief A 640x480 B, G, R image of the same geometry as EdgeImage: a green object (B, G, R
/// 70, 165, 95) on the +normal side of the edge, dark background (45), anti-aliased by 4x4
/// supersampling; with clutter a pink region (grey level close to the object's) from 6 px on and
/// white blobs beside the edge. Noise sigma 5 per channel; `grey` is its BT.601 conversion.
struct ColourEdgeImage {
  std::vector<std::uint8_t> bgr, grey;
  Eigen::Vector2d centre{kWidth / 2.0 + 0.3, kHeight / 2.0 - 0.2};
  Eigen::Vector2d dir{std::cos(kAngle), std::sin(kAngle)};
  Eigen::Vector2d normal{-std::sin(kAngle), std::cos(kAngle)};

  explicit ColourEdgeImage(bool clutter)
      : bgr(static_cast<std::size_t>(kWidth) * kHeight * 3), grey(static_cast<std::size_t>(kWidth) * kHeight) {
    const float obj[3] = {70.f, 165.f, 95.f}, bg[3] = {45.f, 45.f, 45.f}, pink[3] = {170.f, 105.f, 190.f};
    std::vector<float> f(bgr.size());
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
        const bool far = clutter && s > 6.0;
        for (int c = 0; c < 3; ++c)
          f[(static_cast<std::size_t>(y) * kWidth + x) * 3 + c] =
              far ? pink[c] : static_cast<float>(bg[c] + (obj[c] - bg[c]) * cover);
      }
    std::mt19937 rng(8);
    if (clutter) {
      std::uniform_real_distribution<double> along(-80.0, 80.0), across(4.0, 12.0), side(0.0, 1.0);
      for (int b = 0; b < 30; ++b) {
        const Eigen::Vector2d c = centre + along(rng) * dir + (side(rng) < 0.5 ? -1.0 : 1.0) * across(rng) * normal;
        for (int y = static_cast<int>(c.y()) - 3; y <= static_cast<int>(c.y()) + 3; ++y)
          for (int x = static_cast<int>(c.x()) - 3; x <= static_cast<int>(c.x()) + 3; ++x)
            if ((Eigen::Vector2d(x, y) - c).norm() < 2.5)
              for (int ch = 0; ch < 3; ++ch) f[(static_cast<std::size_t>(y) * kWidth + x) * 3 + ch] = 250.f;
      }
    }
    std::normal_distribution<double> noise(0.0, 5.0);
    for (std::size_t k = 0; k < bgr.size(); ++k)
      bgr[k] = static_cast<std::uint8_t>(std::clamp(std::lround(f[k] + noise(rng)), 0L, 255L));
    (void)v4r::image::to_grey(colour(), grey.data(), kWidth);
  }

  [[nodiscard]] v4r::image::ColourView colour() const { return {bgr.data(), kWidth, kHeight, 3 * kWidth}; }
  [[nodiscard]] v4r::image::ImageView view() const { return {grey.data(), kWidth, kHeight, kWidth}; }
  /// Prediction of the given length, 3 px off the edge and rotated by 3 degrees (as EdgeImage).
  [[nodiscard]] Segment2 prediction(double length) const {
    const double a = kAngle + 3.0 * 3.14159265358979 / 180.0;
    const Eigen::Vector2d d(std::cos(a), std::sin(a));
    const Eigen::Vector2d c = centre + 3.0 * normal;
    return {c - 0.5 * length * d, c + 0.5 * length * d};
  }
};

/// Tracks with a state whose object side (+normal, where the object lies) was learned on the
/// same image, copied afresh every iteration. With `object_side` false no side is marked (the
/// plain tracker on the same input). `mismatch` spoils the learned grey level so that every
/// candidate fails the check and the fallback (a second search without cues) runs.
void run_cues(benchmark::State& st, const v4r::image::ImageView& grey, const v4r::image::ColourView* colour,
              const Segment2& pred, bool object_side, bool mismatch) {
  LineTracker tracker;
  LineTrackState learned;
  learned.side[1].is_object = object_side;
  if (!tracker.track(grey, pred, learned, colour).found || learned.side[1].learned != object_side) {
    st.SkipWithError("could not learn the object side");
    return;
  }
  learned.polarity = 0;  // as BM_LineTrack: a fresh polarity each call
  if (mismatch) learned.side[1].mean[0] = learned.side[1].mean[0] > 128.f ? 10.f : 250.f;
  int found = 0, fallbacks = 0, rejected = 0;
  for (auto _ : st) {
    LineTrackState state = learned;
    const LineMeasurement m = tracker.track(grey, pred, state, colour);
    benchmark::DoNotOptimize(m);
    benchmark::DoNotOptimize(state);
    found += m.found ? 1 : 0;
    fallbacks += m.cue_fallback ? 1 : 0;
    rejected += m.cue_rejected;
  }
  if (found != static_cast<int>(st.iterations())) st.SkipWithError("edge not found");
  if ((fallbacks > 0) != mismatch) st.SkipWithError("unexpected cue fallback");
  st.counters["channels"] = object_side ? learned.side[1].channels : 0;
  st.counters["rejected"] = static_cast<double>(rejected) / std::max<double>(1.0, static_cast<double>(st.iterations()));
}

/// Grey cue on the grey edge image (compare BM_LineTrack / BM_LineTrackClutter).
void BM_LineTrackCuesGrey(benchmark::State& st) {
  static const EdgeImage img(false);
  run_cues(st, img.view(), nullptr, img.prediction(120.0), true, false);
}
BENCHMARK(BM_LineTrackCuesGrey);

void BM_LineTrackCuesGreyClutter(benchmark::State& st) {
  static const EdgeImage img(true);
  run_cues(st, img.view(), nullptr, img.prediction(120.0), true, false);
}
BENCHMARK(BM_LineTrackCuesGreyClutter);

/// Colour scene, no object side marked: the baseline of the colour cue benchmarks.
void BM_LineTrackColourSceneNoCues(benchmark::State& st) {
  static const ColourEdgeImage img(true);
  const v4r::image::ColourView colour = img.colour();
  run_cues(st, img.view(), &colour, img.prediction(120.0), false, false);
}
BENCHMARK(BM_LineTrackColourSceneNoCues);

/// Colour scene, grey cue only (no colour view passed).
void BM_LineTrackColourSceneGreyCues(benchmark::State& st) {
  static const ColourEdgeImage img(true);
  run_cues(st, img.view(), nullptr, img.prediction(120.0), true, false);
}
BENCHMARK(BM_LineTrackColourSceneGreyCues);

/// Colour cues: grey level + rg chromaticity of the object side, colour sampled at edgels only.
void BM_LineTrackCuesColour(benchmark::State& st) {
  static const ColourEdgeImage img(false);
  const v4r::image::ColourView colour = img.colour();
  run_cues(st, img.view(), &colour, img.prediction(120.0), true, false);
}
BENCHMARK(BM_LineTrackCuesColour);

void BM_LineTrackCuesColourClutter(benchmark::State& st) {
  static const ColourEdgeImage img(true);
  const v4r::image::ColourView colour = img.colour();
  run_cues(st, img.view(), &colour, img.prediction(120.0), true, false);
}
BENCHMARK(BM_LineTrackCuesColourClutter);

/// Worst case: every candidate fails the check, the edge is searched a second time without cues.
void BM_LineTrackCuesFallback(benchmark::State& st) {
  static const EdgeImage img(true);
  run_cues(st, img.view(), nullptr, img.prediction(120.0), true, true);
}
BENCHMARK(BM_LineTrackCuesFallback);

}  // namespace
