// v4r - robust model-based object tracking. MIT licence.
#include "v4r/features/edge_evidence.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "synthetic_images.hpp"

using namespace v4r::features;
using namespace v4r::features::test_images;

namespace {

constexpr int kEvidenceW = 200, kEvidenceH = 160;

/// A straight step edge through (100, 80) at angle `a`, contrast 40 grey levels, noise sigma.
std::vector<std::uint8_t> edge_image(double a, double noise, std::uint32_t seed = 3) {
  const TrueLine line{{100.0, 80.0}, dir(a)};
  return step_edge(kEvidenceW, kEvidenceH, line, 80.0f, 120.0f).quantize(noise, seed);
}

double share_along(const std::vector<std::uint8_t>& img, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                   float thr = 0.0f, EdgeEvidenceParams p = {}) {
  EdgeEvidence ev(p);
  ev.reset();
  ev.add_segment(view_of(img, kEvidenceW, kEvidenceH), a, b, thr);
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
  Canvas c(kEvidenceW, kEvidenceH, 80.0f);
  for (int x = -12; x <= 12; ++x)
    c.half_plane({100.0 + x - 0.5, 0.0}, {1.0, 0.0}, static_cast<float>(80.0 + 20.0 * (1.0 + std::erf(x / 4.0))));
  const auto img = c.quantize(1.0, 5);
  EXPECT_GE(share_along(img, {100.0, 20.0}, {100.0, 140.0}), 0.9);
  EXPECT_LE(share_along(img, {104.5, 20.0}, {104.5, 140.0}), 0.1);
}

TEST(EdgeEvidence, NoiseAloneConfirmsLittleAndTheThresholdFollowsTheCaller) {
  const auto flat = Canvas(kEvidenceW, kEvidenceH, 100.0f).quantize(3.0, 9);
  EXPECT_LE(share_along(flat, {100.0, 20.0}, {100.0, 140.0}), 0.1);
  const auto img = edge_image(0.0, 1.0);  // horizontal; contrast 40 over about 1 px: about 20 grey/px
  EXPECT_GE(share_along(img, {20.0, 80.0}, {180.0, 80.0}, 10.0f), 0.95);
  EXPECT_LE(share_along(img, {20.0, 80.0}, {180.0, 80.0}, 40.0f), 0.05);
}

TEST(EdgeEvidence, SamplesOutsideTheImageAreNotCounted) {
  const auto img = edge_image(0.0, 1.0);
  EdgeEvidence ev;
  ev.reset();
  ev.add_segment(view_of(img, kEvidenceW, kEvidenceH), {100.0, -100.0}, {100.0, -20.0}, 0.0f);
  EXPECT_EQ(ev.samples(), 0);
  EXPECT_EQ(ev.share(), 0.0);
  EXPECT_FALSE(ev.add_sample(view_of(img, kEvidenceW, kEvidenceH), {std::nan(""), 3.0}, {1.0, 0.0}, 0.0f));
  EXPECT_EQ(ev.samples(), 0);
  ev.add_segment(view_of(img, kEvidenceW, kEvidenceH), {20.0, 80.0}, {140.0, 80.0}, 0.0f);
  EXPECT_EQ(ev.samples(), ev.samples_for_length(120.0));
  EXPECT_EQ(ev.matched(), ev.samples());
}
