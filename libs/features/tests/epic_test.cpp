// v4r - robust model-based object tracking. MIT licence.
// Tests of cue integration in the line tracker (paper 4.1, EPIC): the learned appearance of the
// object side(s) of an edge discards stronger background edges, in grey and in colour images,
// and survives shadows and abrupt light changes. Synthetic anti-aliased windows with known
// ground truth; fixed seeds.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <vector>

#include "synthetic_images.hpp"
#include "v4r/features/line_tracker.hpp"

namespace v4r::features {
namespace {

using namespace test_images;  // NOLINT: Canvas, TrueLine, view_of, ... of synthetic_images.hpp

constexpr int kEpicW = 240, kEpicH = 240;
constexpr double kHitTolerance = 0.3;  // pixels: a measurement on the true line
constexpr double kLength = 120.0;      // pixels: predicted segment length

/// Paints a profile across `line`: `regions[0]` for s < 0 (s = signed distance along the line's
/// normal), then `regions[k]` from s = `starts[k]` on (starts increasing).
template <typename V>
Canvas profile(const TrueLine& line, const std::vector<double>& starts, const std::vector<V>& regions) {
  Canvas c(kEpicW, kEpicH, regions[0]);
  for (std::size_t k = 1; k < regions.size(); ++k)
    c.half_plane(line.p + starts[k] * line.normal(), line.normal(), regions[k]);
  return c;
}

/// \brief Counts of a tracking sequence: frames on the true edge, on the distractor, fallbacks.
struct SequenceStats {
  int frames = 0, on_truth = 0, on_distractor = 0, fallbacks = 0;
  ErrorStats err;  // end-point error of the frames on the true edge
};

void classify(const LineMeasurement& m, const TrueLine& truth, const TrueLine& distractor, SequenceStats& s) {
  ++s.frames;
  s.fallbacks += m.cue_fallback ? 1 : 0;
  if (!m.found) return;
  if (truth.error(m.line) < kHitTolerance) {
    ++s.on_truth;
    s.err.add(truth.error(m.line));
  } else if (distractor.error(m.line) < 0.5) {
    ++s.on_distractor;
  }
}

void print(const char* name, const SequenceStats& s) {
  std::printf("[%s] frames %d  on true edge %d  on distractor %d  fallbacks %d  error mean %.3f max %.3f px\n", name,
              s.frames, s.on_truth, s.on_distractor, s.fallbacks, s.err.mean(), s.err.max);
}

/// Object side marked on side 0 (the -normal side, where the tests paint the object face).
LineTrackState object_on_minus_side() {
  LineTrackState s;
  s.side[0].is_object = true;
  return s;
}

// ---------------------------------------------------------------------------------------------

TEST(LineTrackerCues, LearnsTheObjectSideOnly) {
  // Object face 140 on the -normal side, background 60: one frame learns side 0, not side 1.
  LineTracker tracker;
  const TrueLine truth{{120.3, 119.6}, dir(0.7)};
  const auto buf = step_edge(kEpicW, kEpicH, truth, 140.f, 60.f).quantize(6.0, 1);
  LineTrackState state = object_on_minus_side();
  const LineMeasurement m =
      tracker.track(view_of(buf, kEpicW, kEpicH), segment(truth.p + 1.0 * truth.normal(), truth.t, kLength), state);
  ASSERT_TRUE(m.found);
  EXPECT_FALSE(m.cue_fallback);
  EXPECT_EQ(m.cue_rejected, 0);
  EXPECT_LT(truth.error(m.line), kHitTolerance);
  ASSERT_TRUE(state.side[0].learned);
  EXPECT_EQ(state.side[0].channels, 1);
  EXPECT_NEAR(state.side[0].mean[0], 140.0, 3.0);
  // The spread of band means: noise 6 averaged over 3 columns x 3 lines, about 2 grey levels.
  EXPECT_LT(std::sqrt(state.side[0].var[0]), 4.0);
  EXPECT_FALSE(state.side[1].learned);

  // Running update: the face brightens slowly (150); the mean moves by learning_rate of the step.
  const auto brighter = step_edge(kEpicW, kEpicH, truth, 150.f, 60.f).quantize(6.0, 2);
  const float before = state.side[0].mean[0];
  const LineMeasurement m2 =
      tracker.track(view_of(brighter, kEpicW, kEpicH), segment(truth.p, truth.t, kLength), state);
  ASSERT_TRUE(m2.found);
  EXPECT_FALSE(m2.cue_fallback);
  EXPECT_NEAR(state.side[0].mean[0] - before, tracker.params().learning_rate * 10.0, 1.5);
}

TEST(LineTrackerCues, WithoutObjectSidesResultsAreUnchanged) {
  // Old calls (no side marked as object) and use_cues = false give bit-identical results; a
  // learned object side on a clean edge changes nothing either.
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> angle(0.0, kPi), offset(-5.0, 5.0);
  LineTrackerParams off;
  off.use_cues = false;
  LineTracker with_cues, without(off);
  for (int k = 0; k < 40; ++k) {
    const TrueLine truth{{120.2, 119.7}, dir(angle(rng))};
    Canvas c = step_edge(kEpicW, kEpicH, truth, 150.f, 70.f);
    c.half_plane(truth.p + 7.0 * truth.normal(), truth.normal(), 100.f);  // clutter: a weaker second edge
    const auto buf = c.quantize(6.0, 100 + k);
    const Segment2 pred = segment(truth.p + offset(rng) * truth.normal(), truth.t, kLength);
    LineTrackState s1, s2;
    const LineMeasurement a = with_cues.track(view_of(buf, kEpicW, kEpicH), pred, s1);
    const LineMeasurement b = without.track(view_of(buf, kEpicW, kEpicH), pred, s2);
    EXPECT_EQ(a.found, b.found);
    EXPECT_EQ(a.line.a, b.line.a);
    EXPECT_EQ(a.line.b, b.line.b);
    EXPECT_EQ(a.inliers, b.inliers);
    EXPECT_FALSE(a.cue_fallback);
    EXPECT_FALSE(s1.side[0].learned);
    EXPECT_FALSE(s1.side[1].learned);
    // Learned object side, same image (the object edge is the strongest: cues keep it).
    LineTrackState s3 = object_on_minus_side();
    (void)with_cues.track(view_of(buf, kEpicW, kEpicH), pred, s3);
    ASSERT_TRUE(s3.side[0].learned);
    const LineMeasurement c3 = with_cues.track(view_of(buf, kEpicW, kEpicH), pred, s3);
    ASSERT_TRUE(c3.found);
    EXPECT_FALSE(c3.cue_fallback);
    EXPECT_LT(truth.error(c3.line), kHitTolerance);
    EXPECT_LT((c3.line.a - b.line.a).norm(), 0.05);
  }
}

TEST(LineTrackerCues, StrongerBackgroundEdgeIsDiscarded) {
  // Object 140 | background 60 | at D = 5..7 px a stronger background edge 60 -> 230, moving
  // from frame to frame. The polarity state is cleared every frame so that only the appearance
  // cue can tell the two edges apart: without it the stronger edge wins.
  LineTrackerParams off;
  off.use_cues = false;
  LineTracker tracker, plain(off);
  std::mt19937 rng(2024);
  std::uniform_real_distribution<double> dist(5.0, 7.0), shift(-1.0, 1.0), offset(-1.0, 1.0);
  SequenceStats cued, uncued;
  for (int seq = 0; seq < 6; ++seq) {
    const double th = 0.2 + seq * kPi / 6.0;
    const Eigen::Vector2d base(120.3, 119.8);
    // Frame 0: the object edge alone; the object side's appearance is learned.
    TrueLine truth{base, dir(th)};
    const auto clean = profile<float>(truth, {0.0, 0.0}, {140.f, 60.f}).quantize(6.0, 50 + seq);
    LineTrackState state = object_on_minus_side();
    ASSERT_TRUE(tracker.track(view_of(clean, kEpicW, kEpicH), segment(base, truth.t, kLength), state).found);
    ASSERT_TRUE(state.side[0].learned);
    for (int f = 1; f <= 12; ++f) {
      truth.p = base + shift(rng) * truth.normal();
      const double d = dist(rng);
      const TrueLine distractor{truth.p + d * truth.normal(), truth.t};
      const auto buf = profile<float>(truth, {0.0, 0.0, d}, {140.f, 60.f, 230.f}).quantize(6.0, 1000 * seq + f);
      const Segment2 pred = segment(truth.p + offset(rng) * truth.normal(), truth.t, kLength);
      state.polarity = 0;
      classify(tracker.track(view_of(buf, kEpicW, kEpicH), pred, state), truth, distractor, cued);
      LineTrackState fresh;
      classify(plain.track(view_of(buf, kEpicW, kEpicH), pred, fresh), truth, distractor, uncued);
    }
  }
  print("grey, opposite-sign distractor, cues", cued);
  print("grey, opposite-sign distractor, no cues", uncued);
  EXPECT_EQ(cued.on_truth, cued.frames);
  EXPECT_EQ(cued.fallbacks, 0);
  EXPECT_LE(cued.err.max, kHitTolerance);
  EXPECT_EQ(uncued.on_distractor, uncued.frames);
}

TEST(LineTrackerCues, StrongerSameSignBackgroundEdgeIsDiscarded) {
  // Object 140 | background 60 | a bright background strip 230 | 20 beyond: the 230 -> 20 edge
  // at D = 7.5..9 px has the object edge's sign and 2.6x its strength, so the polarity state does
  // not help. The window is widened (half_width 12) to hold both edges.
  LineTrackerParams p;
  p.half_width = 12;
  LineTrackerParams off = p;
  off.use_cues = false;
  LineTracker tracker(p), plain(off);
  std::mt19937 rng(77);
  std::uniform_real_distribution<double> dist(7.5, 9.0), shift(-1.0, 1.0), offset(-0.5, 0.5);
  SequenceStats cued, uncued;
  for (int seq = 0; seq < 6; ++seq) {
    const double th = 0.1 + seq * kPi / 6.0;
    const Eigen::Vector2d base(119.6, 120.4);
    TrueLine truth{base, dir(th)};
    const auto clean = profile<float>(truth, {0.0, 0.0}, {140.f, 60.f}).quantize(6.0, 70 + seq);
    LineTrackState state = object_on_minus_side();
    ASSERT_TRUE(tracker.track(view_of(clean, kEpicW, kEpicH), segment(base, truth.t, kLength), state).found);
    LineTrackState plain_state = state;  // the same learned polarity, no cues
    for (int f = 1; f <= 12; ++f) {
      truth.p = base + shift(rng) * truth.normal();
      const double d = dist(rng);
      const TrueLine distractor{truth.p + d * truth.normal(), truth.t};
      const auto buf =
          profile<float>(truth, {0.0, 0.0, 2.5, d}, {140.f, 60.f, 230.f, 20.f}).quantize(6.0, 2000 * seq + f);
      const Segment2 pred = segment(truth.p + offset(rng) * truth.normal(), truth.t, kLength);
      const LineMeasurement m = tracker.track(view_of(buf, kEpicW, kEpicH), pred, state);
      classify(m, truth, distractor, cued);
      EXPECT_GT(m.cue_rejected, 0);
      classify(plain.track(view_of(buf, kEpicW, kEpicH), pred, plain_state), truth, distractor, uncued);
      ASSERT_EQ(plain_state.polarity, -1);
    }
  }
  print("grey, same-sign distractor, cues", cued);
  print("grey, same-sign distractor, polarity only", uncued);
  EXPECT_EQ(cued.on_truth, cued.frames);
  EXPECT_EQ(cued.fallbacks, 0);
  EXPECT_LE(cued.err.max, kHitTolerance);
  EXPECT_EQ(uncued.on_distractor, uncued.frames);
}

TEST(LineTrackerCues, InteriorEdgeChecksBothFaces) {
  // An edge between two visible faces A (140) | B (90); beyond B, background that looks like A
  // (140) ends in a strong same-sign edge 140 -> 20 at D. That edge's - side matches face A, only
  // its + side (20, not B) gives it away: with one object side it wins, with both it is discarded.
  LineTrackerParams p;
  p.half_width = 14;
  LineTracker tracker(p);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> dist(9.5, 11.0), offset(-0.5, 0.5);
  SequenceStats both, one;
  for (int seq = 0; seq < 6; ++seq) {
    const TrueLine truth{{120.4, 119.7}, dir(0.3 + seq * kPi / 6.0)};
    const auto clean = profile<float>(truth, {0.0, 0.0}, {140.f, 90.f}).quantize(6.0, 300 + seq);
    LineTrackState s_both = object_on_minus_side();
    s_both.side[1].is_object = true;
    LineTrackState s_one = object_on_minus_side();
    const Segment2 p0 = segment(truth.p, truth.t, kLength);
    ASSERT_TRUE(tracker.track(view_of(clean, kEpicW, kEpicH), p0, s_both).found);
    ASSERT_TRUE(tracker.track(view_of(clean, kEpicW, kEpicH), p0, s_one).found);
    ASSERT_TRUE(s_both.side[1].learned);
    EXPECT_NEAR(s_both.side[1].mean[0], 90.0, 3.0);
    for (int f = 1; f <= 8; ++f) {
      const double d = dist(rng);
      const TrueLine distractor{truth.p + d * truth.normal(), truth.t};
      const auto buf =
          profile<float>(truth, {0.0, 0.0, 5.0, d}, {140.f, 90.f, 140.f, 20.f}).quantize(6.0, 3000 * seq + f);
      const Segment2 pred = segment(truth.p + offset(rng) * truth.normal(), truth.t, kLength);
      classify(tracker.track(view_of(buf, kEpicW, kEpicH), pred, s_both), truth, distractor, both);
      classify(tracker.track(view_of(buf, kEpicW, kEpicH), pred, s_one), truth, distractor, one);
    }
  }
  print("interior edge, both faces", both);
  print("interior edge, one face", one);
  EXPECT_EQ(both.on_truth, both.frames);
  EXPECT_EQ(both.fallbacks, 0);
  EXPECT_EQ(one.on_distractor, one.frames);
}

// Colours (B, G, R) of the colour tests: the object is a green sponge; a pink background region
// has nearly the sponge's grey level (BT.601: 133.4 and 137.8) but another chromaticity.
const Bgr kSponge{70.f, 165.f, 95.f};
const Bgr kBackground{45.f, 45.f, 45.f};
const Bgr kPink{170.f, 105.f, 190.f};
const Bgr kBlack{20.f, 20.f, 20.f};

TEST(LineTrackerCues, ColourSeparatesWhatGreyCannot) {
  // Sponge | dark background | pink strip | black at D = 7.5..9 px: the pink -> black edge is
  // 1.3x stronger than the sponge's, has its sign and a side of the sponge's grey level. The grey
  // cue keeps it (and it wins); the rg chromaticity discards it.
  ASSERT_NEAR(kSponge.grey(), kPink.grey(), 5.0);
  LineTrackerParams p;
  p.half_width = 12;
  LineTracker tracker(p);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> dist(7.5, 9.0), shift(-1.0, 1.0), offset(-0.5, 0.5);
  SequenceStats colour, grey;
  for (int seq = 0; seq < 6; ++seq) {
    const Eigen::Vector2d base(120.2, 119.9);
    TrueLine truth{base, dir(0.25 + seq * kPi / 6.0)};
    const ColourFrame clean(profile<Bgr>(truth, {0.0, 0.0}, {kSponge, kBackground}), 5.0, 400 + seq);
    LineTrackState s_colour = object_on_minus_side();
    const Segment2 p0 = segment(base, truth.t, kLength);
    const image::ColourView cv = clean.colour();
    ASSERT_TRUE(tracker.track(clean.grey_view(), p0, s_colour, &cv).found);
    ASSERT_TRUE(s_colour.side[0].learned);
    ASSERT_EQ(s_colour.side[0].channels, 3);
    EXPECT_NEAR(s_colour.side[0].mean[1], 95.0 / 330.0, 0.01);  // r
    EXPECT_NEAR(s_colour.side[0].mean[2], 165.0 / 330.0, 0.01);  // g
    LineTrackState s_grey = object_on_minus_side();
    ASSERT_TRUE(tracker.track(clean.grey_view(), p0, s_grey).found);
    ASSERT_EQ(s_grey.side[0].channels, 1);
    for (int f = 1; f <= 12; ++f) {
      truth.p = base + shift(rng) * truth.normal();
      const double d = dist(rng);
      const TrueLine distractor{truth.p + d * truth.normal(), truth.t};
      const ColourFrame frame(profile<Bgr>(truth, {0.0, 0.0, 2.5, d}, {kSponge, kBackground, kPink, kBlack}), 5.0,
                              4000 * seq + f);
      const Segment2 pred = segment(truth.p + offset(rng) * truth.normal(), truth.t, kLength);
      const image::ColourView view = frame.colour();
      classify(tracker.track(frame.grey_view(), pred, s_colour, &view), truth, distractor, colour);
      classify(tracker.track(frame.grey_view(), pred, s_grey), truth, distractor, grey);
    }
  }
  print("colour cues", colour);
  print("grey cues on the colour scene", grey);
  EXPECT_EQ(colour.on_truth, colour.frames);
  EXPECT_EQ(colour.fallbacks, 0);
  EXPECT_LE(colour.err.max, kHitTolerance);
  EXPECT_EQ(grey.on_distractor, grey.frames);
}

TEST(LineTrackerCues, ColourShadowKeepsTheTrueEdge) {
  // The sponge darkens by 40 % between frames while the pink/black distractor is present: the
  // grey level of the object side drops out of its grey tolerance, the chromaticity does not
  // change, so the true edge is kept without a fallback; the learned intensity follows the shadow.
  LineTrackerParams p;
  p.half_width = 12;
  LineTracker tracker(p);
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> dist(7.5, 9.0), offset(-0.5, 0.5);
  SequenceStats shadow;
  for (int seq = 0; seq < 6; ++seq) {
    const TrueLine truth{{119.8, 120.3}, dir(0.4 + seq * kPi / 6.0)};
    const ColourFrame clean(profile<Bgr>(truth, {0.0, 0.0}, {kSponge, kBackground}), 5.0, 500 + seq);
    LineTrackState state = object_on_minus_side();
    const image::ColourView cv = clean.colour();
    ASSERT_TRUE(tracker.track(clean.grey_view(), segment(truth.p, truth.t, kLength), state, &cv).found);
    const float lit = state.side[0].mean[0];
    for (int f = 1; f <= 6; ++f) {
      const double d = dist(rng);
      const TrueLine distractor{truth.p + d * truth.normal(), truth.t};
      const ColourFrame frame(
          profile<Bgr>(truth, {0.0, 0.0, 2.5, d}, {kSponge.scaled(0.6f), kBackground, kPink, kBlack}), 5.0,
          5000 * seq + f);
      const Segment2 pred = segment(truth.p + offset(rng) * truth.normal(), truth.t, kLength);
      const image::ColourView view = frame.colour();
      const LineMeasurement m = tracker.track(frame.grey_view(), pred, state, &view);
      classify(m, truth, distractor, shadow);
    }
    // The running mean moved most of the way to the shadowed grey level (0.6 * 133).
    EXPECT_LT(state.side[0].mean[0], 0.6f * lit + 0.15f * lit);
  }
  print("colour shadow (-40 %) with distractor", shadow);
  EXPECT_EQ(shadow.on_truth, shadow.frames);
  EXPECT_EQ(shadow.fallbacks, 0);
}

TEST(LineTrackerCues, AnOutlineOfTheBackgroundsGreyIsNotTakenForATextureLineInside) {
  // A green face against a grey background of the same brightness: the outline shows on the
  // colour gradient only. A dark texture band 6-9 px inside the face makes two strong grey edges
  // with the face's colour on both sides. Learned on a clean frame (object side green, outside
  // grey), the tracker keeps the outline: the band's edges have the object's colour outside
  // (outside_distinct_k), and the colour gradient is searched with the cues before the grey one
  // without them (colour_before_fallback). Without both, the band's grey edge wins.
  const float g = kSponge.grey();
  const Bgr background{g, g, g};
  auto run = [&](const LineTrackerParams& p) {
    LineTracker tracker(p);
    std::mt19937 rng(14);
    std::uniform_real_distribution<double> offset(-3.5, -2.5);
    SequenceStats stats;
    for (int seq = 0; seq < 6; ++seq) {
      const TrueLine truth{{120.1, 119.7}, dir(0.3 + seq * kPi / 6.0)};
      const ColourFrame clean(profile<Bgr>(truth, {0.0, 0.0}, {kSponge, background}), 3.0, 600 + seq);
      LineTrackState state = object_on_minus_side();
      const image::ColourView cv = clean.colour();
      EXPECT_TRUE(tracker.track(clean.grey_view(), segment(truth.p, truth.t, kLength), state, &cv).found);
      const TrueLine band{truth.p - 6.0 * truth.normal(), truth.t};
      for (int f = 1; f <= 6; ++f) {
        const ColourFrame frame(profile<Bgr>(truth, {0.0, -9.0, -6.0, 0.0},
                                             {kSponge, kSponge.scaled(0.6f), kSponge, background}),
                                3.0, 6000 * seq + f);
        // Predicted 2.5-3.5 px towards the band: both within the window.
        const Segment2 pred = segment(truth.p + offset(rng) * truth.normal(), truth.t, kLength);
        const image::ColourView view = frame.colour();
        classify(tracker.track(frame.grey_view(), pred, state, &view), truth, band, stats);
      }
    }
    return stats;
  };
  LineTrackerParams p;
  p.half_width = 12;
  const SequenceStats with = run(p);
  p.outside_distinct_k = 0.0;
  p.colour_before_fallback = false;
  const SequenceStats without = run(p);
  print("outline vs texture band, outside check", with);
  print("outline vs texture band, without", without);
  EXPECT_EQ(with.on_truth, with.frames);
  EXPECT_LE(with.err.max, 0.3);
  EXPECT_EQ(without.on_truth, 0);
  EXPECT_GE(without.on_distractor, without.frames / 2);
}

TEST(LineTrackerCues, GreyShadowFallsBackAndRelearns) {
  // Grey only: the object face darkens by 40 % (140 -> 84). The grey cue rejects the true edge,
  // the tracker falls back to no cues (the edge is the only one), reports it, and relearns; in
  // the next frames a stronger background edge appears and the relearned cue discards it.
  LineTracker tracker;
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> dist(5.0, 7.0), offset(-1.0, 1.0);
  SequenceStats after;
  for (int seq = 0; seq < 6; ++seq) {
    const TrueLine truth{{120.1, 119.4}, dir(0.5 + seq * kPi / 6.0)};
    const auto clean = profile<float>(truth, {0.0, 0.0}, {140.f, 60.f}).quantize(6.0, 600 + seq);
    LineTrackState state = object_on_minus_side();
    ASSERT_TRUE(tracker.track(view_of(clean, kEpicW, kEpicH), segment(truth.p, truth.t, kLength), state).found);
    const auto dark = profile<float>(truth, {0.0, 0.0}, {84.f, 60.f}).quantize(6.0, 700 + seq);
    const LineMeasurement m =
        tracker.track(view_of(dark, kEpicW, kEpicH), segment(truth.p + 0.5 * truth.normal(), truth.t, kLength), state);
    ASSERT_TRUE(m.found);
    EXPECT_TRUE(m.cue_fallback);
    EXPECT_GT(m.cue_rejected, 0);
    EXPECT_LT(truth.error(m.line), kHitTolerance);
    EXPECT_NEAR(state.side[0].mean[0], 84.0, 3.0);  // relearned from scratch
    for (int f = 1; f <= 6; ++f) {
      const double d = dist(rng);
      const TrueLine distractor{truth.p + d * truth.normal(), truth.t};
      const auto buf = profile<float>(truth, {0.0, 0.0, d}, {84.f, 60.f, 230.f}).quantize(6.0, 6000 * seq + f);
      state.polarity = 0;  // only the cue separates the edges (see StrongerBackgroundEdgeIsDiscarded)
      classify(tracker.track(view_of(buf, kEpicW, kEpicH),
                             segment(truth.p + offset(rng) * truth.normal(), truth.t, kLength), state),
               truth, distractor, after);
    }
  }
  print("grey shadow, relearned, then distractor", after);
  EXPECT_EQ(after.on_truth, after.frames);
  EXPECT_EQ(after.fallbacks, 0);
}

TEST(LineTrackerCues, OccludedObjectEdgeFallsBackWithoutRelearningFromAPoorFit) {
  // The object edge is gone (the window sees background only, with a weak partial edge): every
  // candidate fails the cue, the fallback's fit is poor, and the learned appearance is kept.
  LineTracker tracker;
  const TrueLine truth{{120.5, 120.5}, dir(1.0)};
  const auto clean = profile<float>(truth, {0.0, 0.0}, {140.f, 60.f}).quantize(6.0, 801);
  LineTrackState state = object_on_minus_side();
  const Segment2 pred = segment(truth.p, truth.t, kLength);
  ASSERT_TRUE(tracker.track(view_of(clean, kEpicW, kEpicH), pred, state).found);
  const SideAppearance learned = state.side[0];
  // A background edge 200 | 60 (the object edge's sign) along half the window only: inlier ratio
  // about 0.5, below learn_min_inlier_ratio.
  Canvas c(kEpicW, kEpicH, 60.f);
  c.paint(
      [&](double x, double y) {
        const Eigen::Vector2d q(x, y);
        return std::max((q - truth.p).dot(truth.normal()), -(q - truth.p).dot(truth.t));
      },
      200.f);
  const auto buf = c.quantize(6.0, 802);
  const LineMeasurement m = tracker.track(view_of(buf, kEpicW, kEpicH), pred, state);
  EXPECT_TRUE(m.cue_fallback);
  ASSERT_TRUE(m.found);
  EXPECT_LT(m.inlier_ratio, tracker.params().learn_min_inlier_ratio);
  EXPECT_EQ(state.side[0].mean[0], learned.mean[0]);
  EXPECT_EQ(state.side[0].var[0], learned.var[0]);
}

TEST(LineTrackerCues, ColourViewOfAnotherSizeIsIgnored) {
  const TrueLine truth{{120.3, 120.1}, dir(0.9)};
  const ColourFrame frame(profile<Bgr>(truth, {0.0, 0.0}, {kSponge, kBackground}), 5.0, 900);
  image::ColourView wrong = frame.colour();
  wrong.width -= 1;
  LineTracker tracker;
  const Segment2 pred = segment(truth.p, truth.t, kLength);
  LineTrackState s1 = object_on_minus_side(), s2 = object_on_minus_side();
  const LineMeasurement a = tracker.track(frame.grey_view(), pred, s1, &wrong);
  const LineMeasurement b = tracker.track(frame.grey_view(), pred, s2);
  ASSERT_TRUE(a.found);
  EXPECT_EQ(a.line.a, b.line.a);
  EXPECT_EQ(s1.side[0].channels, 1);
  EXPECT_EQ(s1.side[0].mean[0], s2.side[0].mean[0]);
}

TEST(LineTrackerCues, GreyAndColourFramesMix) {
  // A side learned in colour keeps its chromaticity through a grey-only frame (the grey level is
  // updated); a side learned in grey gains chromaticity from its first colour frame.
  const TrueLine truth{{119.7, 120.2}, dir(2.4)};
  const ColourFrame frame(profile<Bgr>(truth, {0.0, 0.0}, {kSponge, kBackground}), 5.0, 910);
  const image::ColourView cv = frame.colour();
  const Segment2 pred = segment(truth.p, truth.t, kLength);
  LineTracker tracker;
  LineTrackState s = object_on_minus_side();
  ASSERT_TRUE(tracker.track(frame.grey_view(), pred, s, &cv).found);
  ASSERT_EQ(s.side[0].channels, 3);
  const SideAppearance colour_learned = s.side[0];
  const ColourFrame brighter(profile<Bgr>(truth, {0.0, 0.0}, {kSponge.scaled(1.1f), kBackground}), 5.0, 911);
  const LineMeasurement m = tracker.track(brighter.grey_view(), pred, s);  // grey only
  ASSERT_TRUE(m.found);
  EXPECT_FALSE(m.cue_fallback);
  EXPECT_EQ(s.side[0].channels, 3);
  EXPECT_EQ(s.side[0].mean[1], colour_learned.mean[1]);
  EXPECT_EQ(s.side[0].mean[2], colour_learned.mean[2]);
  EXPECT_NEAR(s.side[0].mean[0] - colour_learned.mean[0], 0.3 * 0.1 * kSponge.grey(), 1.5);

  LineTrackState g = object_on_minus_side();
  ASSERT_TRUE(tracker.track(frame.grey_view(), pred, g).found);
  ASSERT_EQ(g.side[0].channels, 1);
  ASSERT_TRUE(tracker.track(frame.grey_view(), pred, g, &cv).found);
  EXPECT_EQ(g.side[0].channels, 3);
  EXPECT_NEAR(g.side[0].mean[1], colour_learned.mean[1], 0.005);
}

TEST(LineTrackerCues, EdgelNearWindowBorderSamplesBeyondTheWindow) {
  // The true edge 9 px off the prediction: its side band (2..4 px further out) lies beyond the
  // window's 10 columns and is sampled from the image; a learned side still accepts it.
  LineTracker tracker;
  const TrueLine truth{{120.0, 120.0}, dir(2.0)};
  const auto buf = profile<float>(truth, {0.0, 0.0}, {60.f, 140.f}).quantize(6.0, 950);
  LineTrackState state;
  state.side[1].is_object = true;  // the object on the + side this time
  ASSERT_TRUE(tracker.track(view_of(buf, kEpicW, kEpicH), segment(truth.p, truth.t, kLength), state).found);
  ASSERT_TRUE(state.side[1].learned);
  EXPECT_FALSE(state.side[0].learned);
  EXPECT_NEAR(state.side[1].mean[0], 140.0, 3.0);
  const LineMeasurement m =
      tracker.track(view_of(buf, kEpicW, kEpicH), segment(truth.p - 7.5 * truth.normal(), truth.t, kLength), state);
  ASSERT_TRUE(m.found);
  EXPECT_FALSE(m.cue_fallback);
  EXPECT_EQ(m.cue_rejected, 0);
  EXPECT_LT(truth.error(m.line), kHitTolerance);
}

}  // namespace
}  // namespace v4r::features
