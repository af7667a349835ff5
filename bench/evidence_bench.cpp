// v4r - robust model-based object tracking. MIT licence.
// Micro benchmark of the edge-evidence test (features::EdgeEvidence): the vision cycle runs it over
// the whole projected model once per frame, and again for a per-sample pose.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "v4r/features/edge_evidence.hpp"

namespace {

constexpr int kWidth = 640, kHeight = 480;
constexpr int kSamples = 256;
constexpr double kRadius = 100.0;

/// \brief A 640x480 grey image of a disc (radius 100 px, 60 inside, 180 outside, anti-aliased by
/// 4x4 supersampling at the rim), Gaussian noise sigma 6: edges in every direction.
struct DiscImage {
  std::vector<std::uint8_t> px;
  Eigen::Vector2d centre{kWidth / 2.0 + 0.3, kHeight / 2.0 - 0.2};

  DiscImage() : px(static_cast<std::size_t>(kWidth) * kHeight) {
    std::mt19937 rng(11);
    std::normal_distribution<double> noise(0.0, 6.0);
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x) {
        int in = 0;
        for (int k = 0; k < 16; ++k)
          in += (Eigen::Vector2d(x + (k % 4 + 0.5) / 4 - 0.5, y + (k / 4 + 0.5) / 4 - 0.5) - centre).norm() < kRadius;
        const double v = 180.0 - 120.0 * in / 16.0 + noise(rng);
        px[static_cast<std::size_t>(y) * kWidth + x] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
      }
  }
  [[nodiscard]] v4r::image::ImageView view() const { return {px.data(), kWidth, kHeight, kWidth}; }
};

/// 256 samples around the rim, each predicted 1 px outside it, with its radial normal.
void BM_EdgeEvidence(benchmark::State& st) {
  static const DiscImage img;
  const v4r::image::ImageView view = img.view();
  std::vector<Eigen::Vector2d> p, n;
  for (int k = 0; k < kSamples; ++k) {
    const double a = 2.0 * 3.14159265358979 * (k + 0.37) / kSamples;
    n.emplace_back(std::cos(a), std::sin(a));
    p.push_back(img.centre + (kRadius + 1.0) * n.back());
  }
  v4r::features::EdgeEvidence evidence;
  for (auto _ : st) {
    evidence.reset();
    for (int k = 0; k < kSamples; ++k) evidence.add_sample(view, p[static_cast<std::size_t>(k)], n[static_cast<std::size_t>(k)], 10.0f);
    benchmark::DoNotOptimize(evidence.matched());
  }
  if (evidence.share() < 0.95) st.SkipWithError("the rim is not found");
  st.counters["share"] = evidence.share();
  st.SetItemsProcessed(st.iterations() * kSamples);
}
BENCHMARK(BM_EdgeEvidence);

}  // namespace
