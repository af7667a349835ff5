// v4r - robust model-based object tracking. MIT licence.
// Tests of the oriented-window line tracker on synthetic anti-aliased edge images with known
// sub-pixel ground truth, under noise, clutter, occlusion and bad predictions.
#include "v4r/features/line_tracker.hpp"

#include "synthetic_images.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <new>
#include <random>
#include <vector>

// Counting global allocator: lets a test check that track() does not allocate.
namespace {
std::atomic<long> g_allocations{0};
}  // namespace

// GCC cannot see that the replaced operator new below is malloc-based and warns on free().
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop

namespace v4r::features {
namespace {

using namespace test_images;  // NOLINT: Canvas, TrueLine, view_of, ... of synthetic_images.hpp

// ---------------------------------------------------------------------------------------------

TEST(LineTracker, AccuracyOverRandomAnglesAndOffsets) {
  constexpr int kW = 240, kH = 240, kCases = 200;
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> angle(0.0, kPi), offset(-6.0, 6.0), frac(-0.5, 0.5);
  std::bernoulli_distribution flip(0.5);
  LineTracker tracker;
  ErrorStats err, offset_err;
  int found = 0;
  for (int k = 0; k < kCases; ++k) {
    const TrueLine truth{{kW / 2 + frac(rng), kH / 2 + frac(rng)}, dir(angle(rng))};
    const bool positive = flip(rng);
    const Canvas canvas = step_edge(kW, kH, truth, positive ? 60.f : 180.f, positive ? 180.f : 60.f);
    const auto buf = canvas.quantize(6.0, 1000 + k);
    const double o = offset(rng);
    const Segment2 pred = segment(truth.p + o * truth.normal(), truth.t, 120.0);
    LineTrackState state;
    const LineMeasurement m = tracker.track(view_of(buf, kW, kH), pred, state);
    if (!m.found) continue;
    ++found;
    err.add(truth.distance(m.line.a));
    err.add(truth.distance(m.line.b));
    offset_err.add(std::abs(m.offset_px + o));
    EXPECT_EQ(m.polarity, positive ? 1 : -1);
    EXPECT_EQ(state.polarity, m.polarity);
    EXPECT_GE(m.inlier_ratio, 0.9);
    EXPECT_LT(m.rms_px, 0.5);
    // a->b keeps the direction of the prediction.
    EXPECT_GT((m.line.b - m.line.a).dot(pred.b - pred.a), 0.0);
  }
  std::printf("[accuracy] found %d/%d  end error mean %.4f px max %.4f px  offset error mean %.4f max %.4f\n",
              found, kCases, err.mean(), err.max, offset_err.mean(), offset_err.max);
  EXPECT_EQ(found, kCases);
  EXPECT_LE(err.mean(), 0.15);
  EXPECT_LE(err.max, 0.3);
  EXPECT_LE(offset_err.max, 0.3);
}

TEST(LineTracker, SubPixelPositionWithoutNoise) {
  // A vertical edge at every tenth of a pixel: the estimator's systematic bias alone.
  constexpr int kW = 120, kH = 160;
  LineTracker tracker;
  ErrorStats err;
  for (int k = 0; k <= 10; ++k) {
    const double x = 60.0 + 0.1 * k;
    const TrueLine truth{{x, 80.0}, {0.0, 1.0}};
    const auto buf = step_edge(kW, kH, truth, 60.f, 180.f).quantize(0.0, 1);
    LineTrackState state;
    const LineMeasurement m = tracker.track(view_of(buf, kW, kH), segment({60.0, 80.0}, truth.t, 120.0), state);
    ASSERT_TRUE(m.found);
    err.add(truth.distance(m.line.a));
    err.add(truth.distance(m.line.b));
    // Direction (0,1): normal is (-1,0), so an edge at larger x has a negative offset.
    EXPECT_NEAR(m.offset_px, -(x - 60.0), 0.1);
    EXPECT_EQ(m.inliers, tracker.params().rows);
    EXPECT_LT(m.rms_px, 0.05);
  }
  std::printf("[sub-pixel, no noise] end error mean %.4f px max %.4f px\n", err.mean(), err.max);
  EXPECT_LE(err.max, 0.1);
}

TEST(LineTracker, RotatedPrediction) {
  constexpr int kW = 240, kH = 240, kCases = 100;
  std::mt19937 rng(777);
  std::uniform_real_distribution<double> angle(0.0, kPi), rot(-10.0 * kPi / 180.0, 10.0 * kPi / 180.0),
      offset(-2.0, 2.0);
  LineTracker tracker;
  ErrorStats err;
  int found = 0;
  for (int k = 0; k < kCases; ++k) {
    const double th = angle(rng);
    const TrueLine truth{{kW / 2.0, kH / 2.0}, dir(th)};
    const auto buf = step_edge(kW, kH, truth, 60.f, 180.f).quantize(6.0, 2000 + k);
    const Segment2 pred = segment(truth.p + offset(rng) * truth.normal(), dir(th + rot(rng)), 120.0);
    LineTrackState state;
    const LineMeasurement m = tracker.track(view_of(buf, kW, kH), pred, state);
    if (!m.found) continue;
    ++found;
    err.add(truth.distance(m.line.a));
    err.add(truth.distance(m.line.b));
  }
  std::printf("[rotated prediction <= 10 deg] found %d/%d  end error mean %.4f px max %.4f px\n", found,
              kCases, err.mean(), err.max);
  EXPECT_EQ(found, kCases);
  EXPECT_LE(err.max, 0.3);
}

TEST(LineTracker, ParallelWeakerEdgeAndClutter) {
  constexpr int kW = 240, kH = 240, kCases = 60;
  std::mt19937 rng(4242);
  std::uniform_real_distribution<double> angle(0.0, kPi), offset(-4.0, 4.0), along(-60.0, 60.0),
      across(-14.0, 14.0), len(4.0, 14.0), radius(1.0, 3.0), uni(0.0, 1.0);
  LineTracker tracker;
  ErrorStats err;
  int found = 0;
  for (int k = 0; k < kCases; ++k) {
    const TrueLine truth{{kW / 2.0 + uni(rng) - 0.5, kH / 2.0 + uni(rng) - 0.5}, dir(angle(rng))};
    const Eigen::Vector2d nrm = truth.normal();
    Canvas c = step_edge(kW, kH, truth, 60.f, 160.f);
    // A weaker edge of the same polarity 6 px away on the bright side.
    c.half_plane(truth.p + 6.0 * nrm, nrm, 200.f);
    // Short bright lines and blobs, kept 2.5 px away from the true edge.
    for (int q = 0; q < 25; ++q) {
      double s = across(rng);
      if (std::abs(s) < 2.5 + 3.0) s += (s < 0 ? -5.5 : 5.5);
      const Eigen::Vector2d p = truth.p + along(rng) * truth.t + s * nrm;
      if (uni(rng) < 0.5) {
        const Eigen::Vector2d q2 = p + len(rng) * dir(angle(rng) * 2.0);
        if (std::min(truth.distance(p), truth.distance(q2)) < 3.5 ||
            ((p - truth.p).dot(nrm) > 0) != ((q2 - truth.p).dot(nrm) > 0))
          continue;  // must not touch or cross the true edge
        c.capsule(p, q2, 0.8, 250.f);
      } else {
        const double r = radius(rng);
        if (truth.distance(p) < r + 2.5) continue;
        c.disc(p, r, uni(rng) < 0.5 ? 250.f : 10.f);
      }
    }
    const auto buf = c.quantize(6.0, 3000 + k);
    const Segment2 pred = segment(truth.p + offset(rng) * nrm, truth.t, 120.0);
    LineTrackState state;
    const LineMeasurement m = tracker.track(view_of(buf, kW, kH), pred, state);
    if (!m.found) continue;
    ++found;
    err.add(truth.distance(m.line.a));
    err.add(truth.distance(m.line.b));
  }
  std::printf("[clutter + parallel edge] found %d/%d  end error mean %.4f px max %.4f px\n", found, kCases,
              err.mean(), err.max);
  EXPECT_EQ(found, kCases);
  EXPECT_LE(err.mean(), 0.15);
  EXPECT_LE(err.max, 0.3);
}

TEST(LineTracker, SearchRangeSplitsAThinWallIntoItsTwoEdges) {
  // A thin bright wall 8 px wide: two edges of opposite polarity, the far one stronger. The
  // prediction of each lies between them (3 px off); split at the middle, each window finds its
  // own edge, never the other one.
  constexpr int kW = 240, kH = 240, kCases = 40;
  std::mt19937 rng(77);
  std::uniform_real_distribution<double> angle(0.0, kPi), uni(0.0, 1.0);
  LineTracker tracker;
  ErrorStats err;
  int found = 0, unsplit_wrong = 0;
  for (int k = 0; k < kCases; ++k) {
    const TrueLine near{{kW / 2.0 + uni(rng) - 0.5, kH / 2.0 + uni(rng) - 0.5}, dir(angle(rng))};
    const Eigen::Vector2d nrm = near.normal();
    const TrueLine far{near.p + 8.0 * nrm, near.t};
    Canvas c = step_edge(kW, kH, near, 90.f, 150.f);  // near edge: +60 along nrm
    c.half_plane(far.p, nrm, 20.f);                   // far edge: 150 -> 20, stronger (-130)
    const auto buf = c.quantize(4.0, 500 + k);
    // Each edge predicted 3 px towards the other; each window may search up to the middle (4 px).
    const Segment2 pred_near = segment(near.p + 3.0 * nrm, near.t, 120.0);
    const Segment2 pred_far = segment(far.p - 3.0 * nrm, far.t, 120.0);
    LineTrackState s1, s2, s3;
    const LineMeasurement m1 = tracker.track(view_of(buf, kW, kH), pred_near, s1, nullptr, SearchRange{-1e9, 1.0});
    if (m1.found) {
      ++found;
      err.add(near.distance(m1.line.a));
      err.add(near.distance(m1.line.b));
    }
    const LineMeasurement m2 = tracker.track(view_of(buf, kW, kH), pred_far, s2, nullptr, SearchRange{-1.0, 1e9});
    if (m2.found) {
      ++found;
      err.add(far.distance(m2.line.a));
      err.add(far.distance(m2.line.b));
    }
    // Unsplit, the near edge's window takes the stronger far edge.
    const LineMeasurement m3 = tracker.track(view_of(buf, kW, kH), pred_near, s3);
    if (m3.found && far.distance(m3.line.a) < 1.0) ++unsplit_wrong;
  }
  std::printf("[thin wall split] found %d/%d  error mean %.4f px max %.4f px; unsplit: %d/%d on the wrong edge\n",
              found, 2 * kCases, err.mean(), err.max, unsplit_wrong, kCases);
  EXPECT_EQ(found, 2 * kCases);
  EXPECT_LE(err.max, 0.5);  // (no measurement on the other edge, 8 px away)
  EXPECT_GT(unsplit_wrong, kCases / 2);  // the split is what makes the difference
}

/// A bright bar `width` px wide (its mid-line `mid`) on a darker ground, smeared across by a
/// motion blur `blur` px long (an exact box blur of the bar's profile), quantised with noise.
std::vector<std::uint8_t> blurred_bar(int w, int h, const TrueLine& mid, double width, double blur, double sigma,
                                      std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(w) * h);
  const Eigen::Vector2d n = mid.normal();
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double d = (Eigen::Vector2d(x, y) - mid.p).dot(n);  // from the mid-line
      // Share of the exposure the pixel sees the bar: [d - blur/2, d + blur/2] against [-width/2, width/2].
      const double lo = std::max(d - 0.5 * blur, -0.5 * width), hi = std::min(d + 0.5 * blur, 0.5 * width);
      const double cover = blur > 0.0 ? std::max(0.0, hi - lo) / blur : (std::abs(d) <= 0.5 * width ? 1.0 : 0.0);
      const double v = 70.0 + 110.0 * cover + noise(rng);
      buf[static_cast<std::size_t>(y) * w + x] = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
    }
  return buf;
}

TEST(LineTracker, APairFollowedAsOneIsMeasuredAtItsMidLineUnderMotionBlur) {
  // A thin plate 4 px wide seen across: its two edges too close for split windows, tracked as one
  // against the pair's mid-line. Motion blur 10 px long across it turns each edge into a gradient
  // plateau as wide as the plate, at the blur's ends: the rising edge's 5 px before the mid-line,
  // the falling one's 5 px after. A window that takes one edge is 5 px off the mid-line; the
  // centre between the strongest edge of each sign (SearchRange::pair_span) is on it. Without
  // blur, the pair's centre is the mid-line too.
  constexpr int kW = 240, kH = 240, kCases = 40;
  std::mt19937 rng(4242);
  std::uniform_real_distribution<double> angle(0.0, kPi), uni(-1.0, 1.0);
  LineTracker tracker;
  for (const double blur : {10.0, 0.0}) {
    ErrorStats pair_err, single_err;
    int pair_found = 0;
    for (int k = 0; k < kCases; ++k) {
      const TrueLine mid{{kW / 2.0 + 0.5 * uni(rng), kH / 2.0 + 0.5 * uni(rng)}, dir(angle(rng))};
      const auto buf = blurred_bar(kW, kH, mid, 4.0, blur, 3.0, 900u + static_cast<unsigned>(k));
      const Segment2 pred = segment(mid.p + uni(rng) * mid.normal(), mid.t, 120.0);  // within 1 px
      LineTrackState s1, s2;
      SearchRange pair;
      pair.pair_span = 12.0;
      const LineMeasurement m = tracker.track(view_of(buf, kW, kH), pred, s1, nullptr, pair);
      if (m.found) {
        ++pair_found;
        pair_err.add(mid.error(m.line));
      }
      const LineMeasurement one = tracker.track(view_of(buf, kW, kH), pred, s2);
      if (one.found) single_err.add(mid.error(one.line));
    }
    std::printf("[pair, blur %.0f px] found %d/%d, from the mid-line mean %.3f px max %.3f px; one edge: mean %.3f px\n", blur,
                pair_found, kCases, pair_err.mean(), pair_err.max, single_err.mean());
    EXPECT_EQ(pair_found, kCases);
    EXPECT_LE(pair_err.max, 0.5);
    if (blur > 0.0) {
      EXPECT_GT(single_err.mean(), 4.0);  // (what the pair's centre corrects)
    }
  }
}

TEST(LineTracker, PolarityStateRejectsStrongerOppositeEdge) {
  constexpr int kW = 240, kH = 240;
  LineTracker tracker;
  for (int k = 0; k < 12; ++k) {
    const TrueLine truth{{kW / 2.0 + 0.3, kH / 2.0 - 0.2}, dir(k * kPi / 12.0 + 0.1)};
    const Eigen::Vector2d nrm = truth.normal();
    const Segment2 pred = segment(truth.p + 2.5 * nrm, truth.t, 120.0);
    // Frame 1: the object edge alone (dark 80 -> bright 140 along the normal).
    const auto clean = step_edge(kW, kH, truth, 80.f, 140.f).quantize(6.0, 4000 + k);
    LineTrackState state;
    const LineMeasurement m1 = tracker.track(view_of(clean, kW, kH), pred, state);
    ASSERT_TRUE(m1.found);
    EXPECT_LT(truth.distance(m1.line.a), 0.3);
    ASSERT_EQ(state.polarity, 1);
    // Frame 2: a stronger opposite edge (140 -> 10) appears 5 px away.
    Canvas c = step_edge(kW, kH, truth, 80.f, 140.f);
    c.half_plane(truth.p + 5.0 * nrm, nrm, 10.f);
    const auto cluttered = c.quantize(6.0, 5000 + k);
    const TrueLine other{truth.p + 5.0 * nrm, truth.t};
    const LineMeasurement m2 = tracker.track(view_of(cluttered, kW, kH), pred, state);
    ASSERT_TRUE(m2.found);
    EXPECT_EQ(m2.polarity, 1);
    EXPECT_LT(truth.distance(m2.line.a), 0.3);
    EXPECT_LT(truth.distance(m2.line.b), 0.3);
    // Without the polarity state, the stronger edge wins: the test above does discriminate.
    LineTrackState fresh;
    const LineMeasurement m3 = tracker.track(view_of(cluttered, kW, kH), pred, fresh);
    ASSERT_TRUE(m3.found);
    EXPECT_EQ(m3.polarity, -1);
    EXPECT_LT(other.distance(m3.line.a), 0.3);
    EXPECT_EQ(fresh.polarity, -1);
  }
}

TEST(LineTracker, ContourAgainstBackgroundThatFlipsPolarity) {
  // The object (grey 120) on the -normal side; the background is bright (200) along the first
  // part of the edge and dark (40) along the rest, so the edge flips sign part-way.
  constexpr int kW = 240, kH = 240;
  LineTracker tracker;
  for (int k = 0; k < 8; ++k) {
    const TrueLine truth{{kW / 2.0 + 0.35, kH / 2.0 - 0.15}, dir(0.2 + k * kPi / 8.0)};
    const Eigen::Vector2d nrm = truth.normal();
    const Eigen::Vector2d split = truth.p - 0.2 * 120.0 * truth.t;  // 30% bright, 70% dark
    Canvas c(kW, kH, 120.f);
    c.half_plane(truth.p, nrm, 200.f);
    c.paint(
        [&](double x, double y) {
          const Eigen::Vector2d q(x, y);
          return std::max(-(q - truth.p).dot(nrm), -(q - split).dot(truth.t));
        },
        40.f);
    const auto buf = c.quantize(6.0, 10000 + k);
    const Segment2 pred = segment(truth.p + 1.5 * nrm, truth.t, 120.0);
    LineTrackState state;
    const LineMeasurement m1 = tracker.track(view_of(buf, kW, kH), pred, state);
    // An edge has one polarity: the fit takes the majority (dark-background) part only, even
    // while the polarity is unknown.
    ASSERT_TRUE(m1.found);
    EXPECT_NEAR(m1.inlier_ratio, 0.7, 0.1);
    EXPECT_EQ(m1.polarity, -1);
    EXPECT_EQ(state.polarity, -1);
    for (const Eigen::Vector2d& p : tracker.last_inliers()) EXPECT_GT((p - split).dot(truth.t), -1.0);
    EXPECT_LT(truth.distance(m1.line.a), 0.3);
    EXPECT_LT(truth.distance(m1.line.b), 0.3);
    // Polarity known: the same part, and a stable result.
    const LineMeasurement m2 = tracker.track(view_of(buf, kW, kH), pred, state);
    ASSERT_TRUE(m2.found);
    EXPECT_NEAR(m2.inlier_ratio, 0.7, 0.1);
    for (const Eigen::Vector2d& p : tracker.last_inliers()) EXPECT_GT((p - split).dot(truth.t), -1.0);
    EXPECT_LT(truth.distance(m2.line.a), 0.3);
    EXPECT_LT(truth.distance(m2.line.b), 0.3);
  }
}

TEST(LineTracker, HalfOccludedWindow) {
  constexpr int kW = 240, kH = 240, kCases = 40;
  std::mt19937 rng(99);
  std::uniform_real_distribution<double> angle(0.0, kPi), offset(-4.0, 4.0);
  LineTracker tracker;
  ErrorStats err, ratio;
  for (int k = 0; k < kCases; ++k) {
    const TrueLine truth{{kW / 2.0 + 0.25, kH / 2.0 + 0.4}, dir(angle(rng))};
    Canvas c = step_edge(kW, kH, truth, 60.f, 180.f);
    // The half of the window beyond the centre (along the edge) is hidden by a flat surface.
    const bool second_half = (k % 2) == 0;
    c.half_plane(truth.p, second_half ? truth.t : Eigen::Vector2d(-truth.t), 120.f);
    const auto buf = c.quantize(6.0, 6000 + k);
    const Segment2 pred = segment(truth.p + offset(rng) * truth.normal(), truth.t, 120.0);
    LineTrackState state;
    const LineMeasurement m = tracker.track(view_of(buf, kW, kH), pred, state);
    ASSERT_TRUE(m.found) << "case " << k;
    ratio.add(m.inlier_ratio);
    EXPECT_NEAR(m.inlier_ratio, 0.5, 0.1);
    err.add(truth.distance(m.line.a));
    err.add(truth.distance(m.line.b));
    for (const Eigen::Vector2d& p : tracker.last_inliers()) {
      const double s = (p - truth.p).dot(truth.t);
      EXPECT_LT(second_half ? s : -s, 1.0) << "inlier on the occluded half";
      EXPECT_LT(truth.distance(p), 1.0);
    }
  }
  std::printf("[half occluded] inlier ratio mean %.3f  end error mean %.4f px max %.4f px\n", ratio.mean(),
              err.mean(), err.max);
  EXPECT_LE(err.mean(), 0.15);
  EXPECT_LE(err.max, 0.3);
}

TEST(LineTracker, FlatNoisyImageFindsNothing) {
  constexpr int kW = 240, kH = 240;
  const auto buf = Canvas(kW, kH, 120.f).quantize(8.0, 7);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> angle(0.0, kPi), pos(70.0, 170.0);
  LineTracker tracker;
  for (int k = 0; k < 100; ++k) {
    LineTrackState state;
    const LineMeasurement m =
        tracker.track(view_of(buf, kW, kH), segment({pos(rng), pos(rng)}, dir(angle(rng)), 120.0), state);
    EXPECT_FALSE(m.found) << "case " << k;
    EXPECT_EQ(state.polarity, 0);
  }
}

TEST(LineTracker, WindowPartlyOutsideImage) {
  constexpr int kW = 240, kH = 240;
  LineTracker tracker;
  const int rows = tracker.params().rows;
  for (int k = 0; k < 8; ++k) {
    // Edge through a point near the left border, the prediction reaching 40 px beyond it.
    const double th = (-60.0 + 15.0 * k) * kPi / 180.0;
    const TrueLine truth{{30.3, 120.2}, dir(th)};
    const auto buf = step_edge(kW, kH, truth, 60.f, 180.f).quantize(6.0, 8000 + k);
    const Segment2 pred = segment(truth.p + 2.0 * truth.normal() - 20.0 * truth.t, truth.t, 120.0);
    // Rows whose centre is inside the image (same geometry as the tracker's window).
    int inside = 0;
    const auto& p = tracker.params();
    for (int i = 0; i < rows; ++i) {
      const double f = p.end_margin + (1.0 - 2.0 * p.end_margin) * i / (rows - 1);
      const Eigen::Vector2d ci = pred.a + f * (pred.b - pred.a);
      if (ci.x() >= 1.0 && ci.y() >= 1.0 && ci.x() <= kW - 2.0 && ci.y() <= kH - 2.0) ++inside;
    }
    ASSERT_LT(inside, rows);
    LineTrackState state;
    const LineMeasurement m = tracker.track(view_of(buf, kW, kH), pred, state);
    ASSERT_TRUE(m.found) << "case " << k;
    EXPECT_LE(m.inliers, inside);
    EXPECT_NEAR(m.inlier_ratio, static_cast<double>(m.inliers) / inside, 1e-12);
    EXPECT_LT(truth.distance(m.line.a), 0.3);
    EXPECT_LT(truth.distance(m.line.b), 0.3);
    for (const Eigen::Vector2d& q : tracker.last_inliers()) {
      EXPECT_GE(q.x(), 0.0);
      EXPECT_LE(q.x(), kW - 1.0);
    }
  }
  // Entirely outside: not found, no crash.
  const auto buf = Canvas(kW, kH, 100.f).quantize(0.0, 1);
  LineTrackState state;
  EXPECT_FALSE(tracker.track(view_of(buf, kW, kH), {{-300.0, -50.0}, {-200.0, -60.0}}, state).found);
  EXPECT_FALSE(tracker.track(view_of(buf, kW, kH), {{1e9, 1e9}, {1e9 + 100.0, 1e9}}, state).found);
}

TEST(LineTracker, EdgeNearImageBorderIsFound) {
  // The window's columns reach past the border (clamped samples), its row centres are inside.
  constexpr int kW = 200, kH = 200;
  const TrueLine truth{{4.4, 100.0}, {0.0, 1.0}};
  const auto buf = step_edge(kW, kH, truth, 180.f, 60.f).quantize(6.0, 11);
  LineTracker tracker;
  LineTrackState state;
  const LineMeasurement m = tracker.track(view_of(buf, kW, kH), segment({6.0, 100.0}, truth.t, 120.0), state);
  ASSERT_TRUE(m.found);
  EXPECT_LT(truth.distance(m.line.a), 0.3);
  EXPECT_LT(truth.distance(m.line.b), 0.3);
}

TEST(LineTracker, EdgeBeyondHalfWidthIsNotFound) {
  constexpr int kW = 240, kH = 240;
  LineTracker tracker;
  const double w = tracker.params().half_width;
  for (int k = 0; k < 12; ++k) {
    const TrueLine truth{{120.0, 120.0}, dir(k * kPi / 12.0)};
    const auto buf = step_edge(kW, kH, truth, 60.f, 180.f).quantize(6.0, 9000 + k);
    for (const double o : {w + 4.0, -(w + 4.0), 2.0 * w}) {
      LineTrackState state;
      const LineMeasurement m = tracker.track(view_of(buf, kW, kH), segment(truth.p + o * truth.normal(), truth.t, 120.0), state);
      EXPECT_FALSE(m.found) << "angle step " << k << " offset " << o;
    }
    // Control: the same edge within range is found.
    LineTrackState state;
    EXPECT_TRUE(tracker.track(view_of(buf, kW, kH), segment(truth.p + (w - 3.0) * truth.normal(), truth.t, 120.0), state).found);
  }
}

TEST(LineTracker, DegenerateInputsAreNotFound) {
  constexpr int kW = 100, kH = 100;
  const TrueLine truth{{50.0, 50.0}, {0.0, 1.0}};
  const auto buf = step_edge(kW, kH, truth, 60.f, 180.f).quantize(0.0, 1);
  const image::ImageView img = view_of(buf, kW, kH);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  LineTracker tracker;
  LineTrackState state;
  EXPECT_FALSE(tracker.track(img, {{50, 50}, {50, 50}}, state).found);
  EXPECT_FALSE(tracker.track(img, {{50, 50}, {50, 52}}, state).found);
  EXPECT_FALSE(tracker.track(img, {{nan, 20}, {50, 80}}, state).found);
  EXPECT_FALSE(tracker.track(img, {{50, 20}, {50, nan}}, state).found);
  EXPECT_FALSE(tracker.track(img, {{50, 20}, {inf, 80}}, state).found);
  EXPECT_FALSE(tracker.track(image::ImageView{}, {{50, 20}, {50, 80}}, state).found);
  EXPECT_EQ(state.polarity, 0);
  EXPECT_TRUE(tracker.last_inliers().empty());
  // Control: the same edge with a sane prediction is found.
  EXPECT_TRUE(tracker.track(img, {{50, 20}, {50, 80}}, state).found);
  // Nonsense parameters are sanitized, not trusted.
  LineTrackerParams bad;
  bad.rows = -5;
  bad.half_width = 0;
  bad.max_candidates_per_row = 0;
  bad.inlier_tolerance = nan;
  bad.end_margin = 3.0;
  LineTracker sane(bad);
  EXPECT_GE(sane.params().rows, 3);
  EXPECT_GE(sane.params().half_width, 2);
  EXPECT_GT(sane.params().inlier_tolerance, 0.0);
  LineTrackState s2;
  (void)sane.track(img, {{50, 20}, {50, 80}}, s2);  // must not crash
}

TEST(LineTracker, LongEdgeIsSubsampledWithFixedRows) {
  constexpr int kW = 640, kH = 480;
  const TrueLine truth{{320.3, 240.6}, dir(0.3)};
  const auto buf = step_edge(kW, kH, truth, 60.f, 180.f).quantize(6.0, 13);
  LineTracker tracker;
  const int rows = tracker.params().rows;
  LineTrackState state;
  const Segment2 pred = segment(truth.p + 3.0 * truth.normal(), dir(0.3 + 0.02), 400.0);
  const LineMeasurement m = tracker.track(view_of(buf, kW, kH), pred, state);
  ASSERT_TRUE(m.found);
  EXPECT_LE(m.inliers, rows);
  EXPECT_GE(m.inliers, rows - 2);
  ASSERT_EQ(static_cast<int>(tracker.last_inliers().size()), m.inliers);
  // The rows cover the whole shortened segment: inliers span ~ (1 - 2 * end_margin) * 400 px.
  double lo = 1e9, hi = -1e9;
  for (const Eigen::Vector2d& p : tracker.last_inliers()) {
    const double s = (p - truth.p).dot(truth.t);
    lo = std::min(lo, s);
    hi = std::max(hi, s);
  }
  EXPECT_GT(hi - lo, 0.7 * 400.0);
  EXPECT_LT(truth.distance(m.line.a), 0.3);
  EXPECT_LT(truth.distance(m.line.b), 0.3);
  EXPECT_NEAR((m.line.b - m.line.a).norm(), (1.0 - 2.0 * tracker.params().end_margin) * 400.0, 2.0);
}

TEST(LineTracker, DeterministicAndAllocationFree) {
  constexpr int kW = 320, kH = 240;
  const TrueLine truth{{160.2, 120.7}, dir(1.1)};
  Canvas c = step_edge(kW, kH, truth, 60.f, 180.f);
  c.half_plane(truth.p + 6.0 * truth.normal(), truth.normal(), 210.f);
  const auto buf = c.quantize(8.0, 21);
  const image::ImageView img = view_of(buf, kW, kH);
  const Segment2 pred = segment(truth.p + 1.5 * truth.normal(), dir(1.15), 150.0);
  LineTrackerParams params;
  params.max_candidates_per_row = 4;  // more edgels than pairs: the random sampler runs
  LineTracker tracker(params);
  LineTrackState s1, s2;
  const LineMeasurement warm = tracker.track(img, pred, s1);  // nothing lazy left
  ASSERT_TRUE(warm.found);

  const long before = g_allocations.load();
  const LineMeasurement m1 = tracker.track(img, pred, s1);
  const LineMeasurement m2 = tracker.track(img, pred, s2);
  const LineMeasurement miss = tracker.track(img, segment({30.0, 30.0}, {1.0, 0.0}, 40.0), s2);
  const LineMeasurement nan =
      tracker.track(img, {{std::numeric_limits<double>::quiet_NaN(), 0.0}, {1.0, 1.0}}, s2);
  const long after = g_allocations.load();
  EXPECT_EQ(after - before, 0) << "track() allocated";
  EXPECT_FALSE(miss.found);
  EXPECT_FALSE(nan.found);

  ASSERT_TRUE(m1.found);
  EXPECT_EQ(m1.line.a, m2.line.a);
  EXPECT_EQ(m1.line.b, m2.line.b);
  EXPECT_EQ(m1.inliers, m2.inliers);
  EXPECT_EQ(m1.rms_px, m2.rms_px);
  EXPECT_LT(truth.distance(m1.line.a), 0.3);
  EXPECT_LT(truth.distance(m1.line.b), 0.3);
}

TEST(LineTracker, CuesWithColourAreDeterministicAndAllocationFree) {
  // Colour cues on both sides (an interior edge), the fallback path and a colour view of the
  // wrong size: no heap allocation in track(), identical results for identical inputs.
  constexpr int kW = 320, kH = 240;
  const TrueLine truth{{160.4, 120.3}, dir(0.6)};
  Canvas c(kW, kH, Bgr{70.f, 165.f, 95.f});
  c.half_plane(truth.p, truth.normal(), Bgr{160.f, 80.f, 60.f});
  c.half_plane(truth.p + 6.0 * truth.normal(), truth.normal(), Bgr{140.f, 70.f, 50.f});  // weak clutter
  const ColourFrame frame(c, 5.0, 31);
  Canvas dark_canvas(kW, kH, Bgr{35.f, 80.f, 45.f});  // the light halves: every cue fails
  dark_canvas.half_plane(truth.p, truth.normal(), Bgr{80.f, 40.f, 30.f});
  const ColourFrame dark(dark_canvas, 5.0, 32);
  const image::ColourView colour = frame.colour(), dark_colour = dark.colour();
  image::ColourView wrong = colour;
  wrong.height -= 2;
  const Segment2 pred = segment(truth.p + 1.2 * truth.normal(), dir(0.63), 150.0);
  LineTrackerParams params;
  params.max_candidates_per_row = 4;
  LineTracker tracker(params);
  LineTrackState s1;
  s1.side[0].is_object = true;
  s1.side[1].is_object = true;
  ASSERT_TRUE(tracker.track(frame.grey_view(), pred, s1, &colour).found);  // learns both sides
  ASSERT_TRUE(s1.side[0].learned && s1.side[1].learned);
  ASSERT_EQ(s1.side[0].channels, 3);
  LineTrackState s2 = s1, s3 = s1;

  const long before = g_allocations.load();
  const LineMeasurement m1 = tracker.track(frame.grey_view(), pred, s1, &colour);
  const LineMeasurement m2 = tracker.track(frame.grey_view(), pred, s2, &colour);
  const LineMeasurement fb = tracker.track(dark.grey_view(), pred, s3, &dark_colour);
  const LineMeasurement w = tracker.track(frame.grey_view(), pred, s3, &wrong);
  const LineMeasurement miss = tracker.track(frame.grey_view(), segment({30.0, 30.0}, {1.0, 0.0}, 40.0), s3, &colour);
  const long after = g_allocations.load();
  EXPECT_EQ(after - before, 0) << "track() allocated";

  ASSERT_TRUE(m1.found);
  EXPECT_FALSE(m1.cue_fallback);
  EXPECT_EQ(m1.line.a, m2.line.a);
  EXPECT_EQ(m1.line.b, m2.line.b);
  EXPECT_EQ(s1.side[0].mean[1], s2.side[0].mean[1]);
  EXPECT_EQ(s1.side[1].var[2], s2.side[1].var[2]);
  EXPECT_LT(truth.error(m1.line), 0.3);
  ASSERT_TRUE(fb.found);
  EXPECT_TRUE(fb.cue_fallback);
  EXPECT_LT(truth.error(fb.line), 0.3);
  EXPECT_TRUE(w.found);
  EXPECT_FALSE(miss.found);
}

}  // namespace
}  // namespace v4r::features
