// v4r - robust model-based object tracking. MIT licence.
#include "v4r/features/edge_evidence.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "synthetic_images.hpp"

using namespace v4r::features;
using namespace v4r::features::test_images;

namespace {

constexpr int kW = 200, kH = 160;

/// A straight step edge through (100, 80) at angle `a`, contrast 40 grey levels, noise sigma.
std::vector<std::uint8_t> edge_image(double a, double noise, std::uint32_t seed = 3) {
  const TrueLine line{{100.0, 80.0}, dir(a)};
  return step_edge(kW, kH, line, 80.0f, 120.0f).quantize(noise, seed);
}

double share_along(const std::vector<std::uint8_t>& img, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                   float thr = 0.0f, EdgeEvidenceParams p = {}) {
  EdgeEvidence ev(p);
  ev.reset();
  ev.add_segment(view_of(img, kW, kH), a, b, thr);
  return ev.share();
}

}  // namespace

TEST(EdgeEvidence, TheEdgeWhereItIsPredictedIsConfirmedUnderNoise) {
  for (double a : {0.0, 0.4, 1.2, 2.0}) {
    const auto img = edge_image(a, 3.0);
    const Eigen::Vector2d c(100.0, 80.0), t = dir(a);
    // Predicted 1.5 px off across: still within the search.
    const Eigen::Vector2d off = 1.5 * Eigen::Vector2d(-t.y(), t.x());
    EXPECT_GE(share_along(img, c - 50.0 * t + off, c + 50.0 * t + off), 0.95) << "angle " << a;
  }
}

TEST(EdgeEvidence, AnEdgeFarFromThePredictionOrAcrossItIsNotConfirmed) {
  const auto img = edge_image(0.3, 2.0);
  const Eigen::Vector2d c(100.0, 80.0), t = dir(0.3), n(-t.y(), t.x());
  // 6 px beside the real edge: no edge there.
  EXPECT_LE(share_along(img, c - 50.0 * t + 6.0 * n, c + 50.0 * t + 6.0 * n), 0.05);
  // Predicted at right angles to the real edge: the gradient's orientation does not match (only
  // the samples right at the crossing may).
  EXPECT_LE(share_along(img, c - 50.0 * n, c + 50.0 * n), 0.1);
}

TEST(EdgeEvidence, ABlurredEdgeIsFoundAtItsCentreNotOnItsFlank) {
  // An edge blurred over about 12 px (erf profile): its gradient exceeds the threshold over
  // several pixels, its maximum lies at the centre line only.
  Canvas c(kW, kH, 80.0f);
  for (int x = -12; x <= 12; ++x)
    c.half_plane({100.0 + x - 0.5, 0.0}, {1.0, 0.0}, static_cast<float>(80.0 + 20.0 * (1.0 + std::erf(x / 4.0))));
  const auto img = c.quantize(1.0, 5);
  EXPECT_GE(share_along(img, {100.0, 20.0}, {100.0, 140.0}), 0.9);
  EXPECT_LE(share_along(img, {104.5, 20.0}, {104.5, 140.0}), 0.1);
}

TEST(EdgeEvidence, NoiseAloneConfirmsLittleAndTheThresholdFollowsTheCaller) {
  const auto flat = Canvas(kW, kH, 100.0f).quantize(3.0, 9);
  EXPECT_LE(share_along(flat, {100.0, 20.0}, {100.0, 140.0}), 0.1);
  const auto img = edge_image(0.0, 1.0);  // horizontal; contrast 40 over about 1 px: about 20 grey/px
  EXPECT_GE(share_along(img, {20.0, 80.0}, {180.0, 80.0}, 10.0f), 0.95);
  EXPECT_LE(share_along(img, {20.0, 80.0}, {180.0, 80.0}, 40.0f), 0.05);
}

TEST(EdgeEvidence, SamplesOutsideTheImageAreNotCounted) {
  const auto img = edge_image(0.0, 1.0);
  EdgeEvidence ev;
  ev.reset();
  ev.add_segment(view_of(img, kW, kH), {100.0, -100.0}, {100.0, -20.0}, 0.0f);
  EXPECT_EQ(ev.samples(), 0);
  EXPECT_EQ(ev.share(), 0.0);
  EXPECT_FALSE(ev.add_sample(view_of(img, kW, kH), {std::nan(""), 3.0}, {1.0, 0.0}, 0.0f));
  EXPECT_EQ(ev.samples(), 0);
  ev.add_segment(view_of(img, kW, kH), {20.0, 80.0}, {140.0, 80.0}, 0.0f);
  EXPECT_EQ(ev.samples(), ev.samples_for_length(120.0));
  EXPECT_EQ(ev.matched(), ev.samples());
}

namespace {

/// The test as specified, computed the plain way: every offset's profile (double-precision
/// clamped bilinear samples), then any local maximum within search_px that passes threshold and
/// orientation. EdgeEvidence computes it lazily from the centre outwards and stops at the first
/// match; both must agree.
bool reference_match(const v4r::image::ImageView& img, const Eigen::Vector2d& p, const Eigen::Vector2d& n, float thr_in,
                     const EdgeEvidenceParams& prm) {
  const int search = prm.search_px, reach = search + 2, along = EdgeEvidence::kAlong;
  const Eigen::Vector2d e(-n.y(), n.x());
  std::vector<double> v(2 * reach + 1), ge(2 * reach + 1), gn(2 * reach + 1, 0.0);
  for (int o = -reach; o <= reach; ++o) {
    double acc = 0.0;
    for (int t = -along; t <= along; ++t) acc += img.sample(p.x() + o * n.x() + t * e.x(), p.y() + o * n.y() + t * e.y());
    v[o + reach] = acc / (2 * along + 1);
    const Eigen::Vector2d q = p + o * n;
    ge[o + reach] = (img.sample(q.x() + along * e.x(), q.y() + along * e.y()) -
                     img.sample(q.x() - along * e.x(), q.y() - along * e.y())) / (2 * along);
  }
  for (int o = -reach + 1; o <= reach - 1; ++o) gn[o + reach] = 0.5 * (v[o + reach + 1] - v[o + reach - 1]);
  const double thr = std::max(thr_in, prm.min_gradient);
  for (int o = -search; o <= search; ++o) {
    const double g = std::abs(gn[o + reach]);
    if (g < thr || g < std::abs(gn[o + reach - 1]) || g < std::abs(gn[o + reach + 1])) continue;
    if (g >= std::cos(prm.max_angle_rad) * std::hypot(gn[o + reach], ge[o + reach])) return true;
  }
  return false;
}

}  // namespace

TEST(EdgeEvidence, TheLazySearchAgreesWithThePlainTestOnTexturedImages) {
  // Random textured scene: discs and bars of random grey levels under noise, sampled at random
  // points and orientations (edges, texture and flat areas alike), for two search widths.
  Canvas c(kW, kH, 100.0f);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> ux(0.0, kW), uy(0.0, kH), ur(3.0, 25.0), ug(20.0, 230.0), ua(0.0, 2.0 * kPi);
  for (int k = 0; k < 40; ++k) c.disc({ux(rng), uy(rng)}, ur(rng), static_cast<float>(ug(rng)));
  for (int k = 0; k < 15; ++k)
    c.capsule({ux(rng), uy(rng)}, {ux(rng), uy(rng)}, 0.5 * ur(rng) / 3.0, static_cast<float>(ug(rng)));
  const auto img = c.quantize(4.0, 21);
  const auto view = view_of(img, kW, kH);
  for (const int search : {1, 2, 4}) {
    EdgeEvidenceParams prm;
    prm.search_px = search;
    EdgeEvidence ev(prm);
    ev.reset();
    int agree = 0, total = 0, matched = 0;
    for (int k = 0; k < 4000; ++k) {
      const Eigen::Vector2d p(ux(rng), uy(rng));
      const double a = ua(rng);
      const Eigen::Vector2d n(std::cos(a), std::sin(a));
      const int before = ev.samples();
      const bool fast = ev.add_sample(view, p, n, 6.0f);
      if (ev.samples() == before) continue;  // outside the image: not counted by either
      const bool plain = reference_match(view, p, n, 6.0f, prm);
      ++total;
      agree += fast == plain ? 1 : 0;
      matched += plain ? 1 : 0;
    }
    ASSERT_GT(total, 3000);
    EXPECT_GT(matched, 100) << "search " << search;          // the scene has edges ...
    EXPECT_LT(matched, 9 * total / 10) << "search " << search;  // ... and flat areas
    // Single-precision sample positions may flip a comparison that is a tie to 1e-4 grey levels.
    EXPECT_GE(agree, total - total / 1000) << "search " << search;
  }
}
