// v4r - robust model-based object tracking. MIT licence.
// The vision cycle: no heap allocation per frame, the time budget's degradation order with a fake
// clock, and losing and regaining track.
#include <atomic>
#include <cstdlib>
#include <new>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "alloc_counter.hpp"
#include "mat_views.hpp"
#include "../../detection/tests/test_templates.hpp"

#include "v4r/detection/template_set.hpp"
#include "v4r/geometry/look_at.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/object_search.hpp"
#include "v4r/pipeline/tracker.hpp"
#include "v4r/synth/renderer.hpp"

// Counting global allocator: counts allocations while `g_counting` is set. GCC cannot see that
// the replaced operator new is malloc-based and warns on free().
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace v4r::test {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
}  // namespace v4r::test
using v4r::test::g_allocations;
using v4r::test::g_counting;
void* operator new(std::size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

using namespace v4r;

namespace {

struct Sequence {
  std::shared_ptr<const model::Model> model;
  std::vector<geometry::SE3> truth;
  std::vector<cv::Mat> grey, bgr;
};

Sequence make(std::string (*cao)(), double distance, int frames) {
  Sequence s;
  auto m = model::parse_cao(cao(), "m");
  s.model = std::make_shared<const model::Model>(std::move(*m));
  synth::TrajectorySpec spec;
  spec.frames = frames;
  spec.T0 = geometry::look_at(distance, -0.6, 0.75);
  s.truth = synth::make_trajectory(spec);
  synth::RenderOptions ro;
  synth::Renderer r(synth::default_camera(), ro);
  for (int i = 0; i < frames; ++i) {
    s.bgr.push_back(r.render(*s.model, s.truth[i], i));
    cv::Mat g(s.bgr.back().rows, s.bgr.back().cols, CV_8UC1);
    for (int y = 0; y < g.rows; ++y)
      for (int x = 0; x < g.cols; ++x) {
        const cv::Vec3b c = s.bgr.back().at<cv::Vec3b>(y, x);
        g.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>((c[0] * 29 + c[1] * 150 + c[2] * 77) >> 8);
      }
    s.grey.push_back(g);
  }
  return s;
}

/// The box with a phantom edge across its top face: a model line without an image edge, missed
/// in every frame (null if the box's .cao text changed).
std::shared_ptr<const model::Model> phantom_box() {
  std::string cao = synth::box_cao();
  const auto replace = [&](const std::string& from, const std::string& to) {
    const auto at = cao.find(from);
    if (at == std::string::npos) return false;
    cao.replace(at, from.size(), to);
    return true;
  };
  if (!replace("# 3D points\n8\n", "# 3D points\n10\n") ||
      !replace("-0.10  0.075  0.05   # 7\n", "-0.10  0.075  0.05   # 7\n-0.05 0.0 0.05\n0.05 0.0 0.05\n") ||
      !replace("# 3D lines\n0\n", "# 3D lines\n1\n8 9\n"))
    return nullptr;
  auto m = model::parse_cao(cao, "box_with_phantom");
  if (!m) return nullptr;
  return std::make_shared<const model::Model>(std::move(*m));
}

using v4r::test::cview;
using v4r::test::view;

}  // namespace

TEST(VisionCycle, AllocatesNothingPerFrame) {
  // Lines, ellipses, junctions, colour cues, the filter and the budget all run; after the first
  // (warm-up) frame the cycle must not touch the heap.
  for (auto cao : {&synth::ship_mockup_cao, &synth::flange_cao}) {
    const Sequence s = make(cao, 0.6, 12);
    pipeline::CycleParams p;
    p.budget.cycle_ms = 5.0;
    pipeline::SingleObjectTracker tracker(s.model, synth::default_camera(), p);
    tracker.set_pose(s.truth[0]);
    g_allocations = 0;
    g_counting = true;
    tracker.track(view(s.grey[0]), cview(s.bgr[0]));
    g_counting = false;
    EXPECT_GT(g_allocations, 0) << "the first frame sizes the buffers (and shows the counter works)";
    long allocations = 0;
    int used = 0;
    for (std::size_t i = 1; i < s.grey.size(); ++i) {
      g_allocations = 0;
      g_counting = true;
      const pipeline::FrameResult r = tracker.track(view(s.grey[i]), cview(s.bgr[i]));
      g_counting = false;
      allocations += g_allocations;
      used += r.report.features_used;
      EXPECT_NE(r.report.status, scene::TrackStatus::kLost);
    }
    EXPECT_EQ(allocations, 0);
    EXPECT_GT(used, 0);
  }
}

namespace {
// A fake clock: every call advances by 1 ms, so every cycle takes several milliseconds.
std::int64_t g_ticks = 0;
Clock::time_point fake_now() { return Clock::time_point(std::chrono::milliseconds(++g_ticks)); }
}  // namespace

TEST(VisionCycle, BudgetDegradesSamplesFirstThenFeaturesAndCountsOverruns) {
  const Sequence s = make(&synth::ship_mockup_cao, 0.6, 3);
  scene::Scene sc;
  sc.add_camera(scene::Camera{"cam", synth::default_camera(), geometry::SE3()});
  ASSERT_TRUE(sc.add_object("ship", s.model));
  sc.set_pose(0, s.truth[0]);
  const pipeline::CameraImage img{view(s.grey[0]), {}};

  pipeline::CycleParams p;
  p.budget.adapt = false;
  p.budget.cost_per_sample_us = 1.0;
  // Enough budget: no degradation.
  p.budget.cycle_ms = 100.0;
  pipeline::VisionCycle generous(p, &fake_now);
  const auto& r0 = generous.process(sc, std::span(&img, 1));
  EXPECT_EQ(r0.degrade_level, 0);
  EXPECT_EQ(r0.features_dropped, 0);
  const int visible = r0.objects[0].features_visible;
  ASSERT_GE(visible, 10);
  // 1 us per sample: visible features need visible * rows us; with 0.75 of the budget usable, a
  // budget between visible * reduced_rows and visible * rows us degrades to fewer rows only.
  const double rows = p.track.rows, reduced = p.budget.reduced_rows;
  ASSERT_LT(reduced, rows);
  sc.set_pose(0, s.truth[0]);
  p.budget.cycle_ms = visible * 0.5 * (rows + reduced) / 0.75 / 1000.0;
  pipeline::VisionCycle tight(p, &fake_now);
  const auto& r1 = tight.process(sc, std::span(&img, 1));
  EXPECT_EQ(r1.degrade_level, 1);
  EXPECT_EQ(r1.features_dropped, 0);
  EXPECT_EQ(r1.objects[0].features_visible, visible);
  // Below visible * reduced_rows us: features are left out too, shortest first, down to what fits.
  sc.set_pose(0, s.truth[0]);
  p.budget.cycle_ms = 8 * reduced / 0.75 / 1000.0;
  pipeline::VisionCycle tighter(p, &fake_now);
  const auto& r2 = tighter.process(sc, std::span(&img, 1));
  EXPECT_EQ(r2.degrade_level, 2);
  EXPECT_EQ(r2.features_dropped, visible - 8);
  EXPECT_EQ(r2.objects[0].features_visible, 8);
  float shortest_kept = 1e9f, longest_dropped = 0.0f;
  for (const auto& f : sc.objects()[0].views[0].lines) {
    if (!f.visible || f.ambiguous) continue;
    const float len = static_cast<float>((f.predicted.b - f.predicted.a).norm());
    if (f.dropped) longest_dropped = std::max(longest_dropped, len);
    else shortest_kept = std::min(shortest_kept, len);
  }
  EXPECT_LE(longest_dropped, shortest_kept + 3.0f);  // (the kept ones were re-projected after the solve)
  // With the fake clock each cycle takes far longer than this budget: every cycle is an overrun.
  EXPECT_EQ(r2.overruns, 1);
  tighter.process(sc, std::span(&img, 1));
  EXPECT_EQ(tighter.process(sc, std::span(&img, 1)).overruns, 3);
  EXPECT_GT(r2.track_ms, 0.0);
}

TEST(VisionCycle, LosesTrackWhenTheObjectVanishesAndRegainsIt) {
  const Sequence s = make(&synth::box_cao, 0.55, 30);
  pipeline::SingleObjectTracker tracker(s.model, synth::default_camera());
  tracker.set_pose(s.truth[0]);
  const cv::Mat empty(s.grey[0].rows, s.grey[0].cols, CV_8UC1, cv::Scalar(70));
  int lost = 0;
  pipeline::FrameResult r;
  for (int i = 0; i < 30; ++i) {
    const bool hidden = i >= 10 && i < 14;  // the object is gone for four frames
    r = tracker.track(view(hidden ? empty : s.grey[i]));
    if (hidden) {
      lost += r.report.status == scene::TrackStatus::kLost;
      // It holds near the last good pose instead of drifting away.
      EXPECT_LT((r.T_cam_obj.translation() - s.truth[9].translation()).norm(), 0.03) << i;
    }
    if (i >= 18) {
      EXPECT_EQ(r.report.status, scene::TrackStatus::kTracking) << i;
      EXPECT_LT((r.T_cam_obj.translation() - s.truth[i].translation()).norm(), 1e-3) << i;
    }
  }
  EXPECT_EQ(lost, 4);
}

TEST(VisionCycle, LongMissedFeaturesAreSearchedOnlyEveryFewFrames) {
  // The box with a phantom edge across its top face: a model line without an image edge, missed
  // in every frame. After search_backoff_frames misses it is searched every
  // search_backoff_period-th frame only; the tracking of the box is the same.
  const auto model = phantom_box();
  ASSERT_TRUE(model);
  const Sequence s = make(&synth::box_cao, 0.55, 30);

  struct Run {
    long windows = 0;
    double max_error_m = 0.0;
  };
  const auto run = [&](int backoff_frames) {
    pipeline::CycleParams p;
    p.search_backoff_frames = backoff_frames;
    pipeline::SingleObjectTracker tracker(model, synth::default_camera(), p);
    tracker.set_pose(s.truth[0]);
    Run r;
    for (int i = 0; i < 30; ++i) {
      const auto res = tracker.track(view(s.grey[i]));
      if (i >= 10) r.windows += tracker.cycle().last_report().windows;
      r.max_error_m = std::max(r.max_error_m, (res.T_cam_obj.translation() - s.truth[i].translation()).norm());
    }
    return r;
  };
  const Run always = run(0), backoff = run(4);
  std::printf("[backoff] windows over frames 10-29: %ld always searched, %ld with back-off; max error %.3f / %.3f mm\n",
              always.windows, backoff.windows, always.max_error_m * 1e3, backoff.max_error_m * 1e3);
  // Every frame: 1 search window for the phantom; with the back-off one frame in four.
  EXPECT_GE(always.windows - backoff.windows, 12);
  EXPECT_LT(backoff.max_error_m, 1e-3);
  EXPECT_LT(always.max_error_m, 1e-3);
}

TEST(VisionCycle, ALinePoseTheImageConfirmsWellIsNotMeasuredAgainBySamples) {
  // The box with a phantom edge across its top face (a model line the image never shows): the
  // line solve leaves that edge unused in every frame, a doubt that starts the per-sample fit,
  // but the image confirms the rest of the model. With samples.doubt_evidence below that share the
  // fit is not run; with 1 it runs in every frame, and changes nothing here: the same poses.
  const auto model = phantom_box();
  ASSERT_TRUE(model);
  const Sequence s = make(&synth::box_cao, 0.55, 20);

  struct Run {
    int fits = 0, kept = 0;
    double min_evidence = 1.0;
    std::vector<geometry::SE3> poses;
  };
  const auto run = [&](double doubt_evidence) {
    pipeline::CycleParams p;
    p.samples.doubt_evidence = doubt_evidence;
    pipeline::SingleObjectTracker tracker(model, synth::default_camera(), p);
    tracker.set_pose(s.truth[0]);
    Run r;
    for (int i = 0; i < 20; ++i) {
      const auto res = tracker.track(view(s.grey[i]));
      using Fit = pipeline::ObjectReport::SampleFit;
      r.fits += res.report.sample_fit != Fit::kNotRun ? 1 : 0;
      r.kept += res.report.sample_fit == Fit::kKept ? 1 : 0;
      r.min_evidence = std::min(r.min_evidence, res.report.evidence);
      r.poses.push_back(res.T_cam_obj);
    }
    return r;
  };
  const Run every = run(1.0);
  const double below = every.min_evidence - 0.05;  // under the share the image confirms in every frame
  ASSERT_GT(below, 0.5);
  const Run gated = run(below);
  std::printf("[doubt evidence] per-sample fits %d (kept %d) with samples.doubt_evidence 1, %d at %.2f\n", every.fits,
              every.kept, gated.fits, below);
  EXPECT_GE(every.fits, 18);
  EXPECT_EQ(every.kept, 0);
  EXPECT_EQ(gated.fits, 0);
  ASSERT_EQ(every.poses.size(), gated.poses.size());
  for (std::size_t i = 0; i < every.poses.size(); ++i) {
    EXPECT_LT((every.poses[i].translation() - gated.poses[i].translation()).norm(), 1e-9) << "frame " << i;
    EXPECT_LT(geometry::rotation_angle_between(every.poses[i], gated.poses[i]), 1e-9) << "frame " << i;
  }
}

TEST(VisionCycle, APoseNotYetConfirmedByTheImageIsNotMeasuredBySamples) {
  // The per-sample fit searches 3 px about the prediction: from a pose just set (a start pose, a
  // search's restart or last frame's found pose) it would hold the pose in place against the
  // line solve's move. It runs
  // only once a frame has confirmed the pose, even with samples.always. The box with a phantom
  // edge, started 1 cm and 2 deg off the truth: no fit on the first frame, one on every frame
  // after, and the truth is reached.
  const auto model = phantom_box();
  ASSERT_TRUE(model);
  const Sequence s = make(&synth::box_cao, 0.55, 6);
  pipeline::CycleParams p;
  p.samples.always = true;
  pipeline::SingleObjectTracker tracker(model, synth::default_camera(), p);
  const geometry::SE3 turn(Eigen::Quaterniond(Eigen::AngleAxisd(2.0 * M_PI / 180.0, Eigen::Vector3d(0.3, 1, 0).normalized())),
                           Eigen::Vector3d::Zero());
  const geometry::SE3 shift(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.01, -0.004, 0.0));
  tracker.set_pose(shift * s.truth[0] * turn);
  using Fit = pipeline::ObjectReport::SampleFit;
  for (std::size_t i = 0; i < s.grey.size(); ++i) {
    const auto res = tracker.track(view(s.grey[i]));
    ASSERT_EQ(res.report.status, scene::TrackStatus::kTracking) << "frame " << i;
    if (i == 0) {
      EXPECT_EQ(res.report.sample_fit, Fit::kNotRun) << "a pose just set";
    } else {
      EXPECT_NE(res.report.sample_fit, Fit::kNotRun) << "frame " << i;
    }
    if (i + 1 == s.grey.size()) {
      EXPECT_LT((res.T_cam_obj.translation() - s.truth[i].translation()).norm(), 0.002);
      EXPECT_LT(geometry::rotation_angle_between(res.T_cam_obj, s.truth[i]), 0.3 * M_PI / 180.0);
    }
  }
}

TEST(VisionCycle, APoseSetAnewIsTrackedAsIfNothingCameBeforeIt) {
  // The search refines hypothesis after hypothesis on one scene object (Scene::set_pose each
  // time): what a pose gives must not depend on the poses tracked before it. One scene tracks a
  // wrong pose (turned and shifted) for three cycles, then is set to a pose near the truth; a
  // fresh scene is set to that pose directly. Both track it to the same pose and evidence.
  const Sequence s = make(&synth::ship_mockup_cao, 0.6, 2);
  const pipeline::CameraImage img{view(s.grey[1]), cview(s.bgr[1])};
  const auto moved = [&](double tx, double ty, double tz, double rx, double ry, double rz) {
    return geometry::SE3::exp((geometry::Vector6d() << tx, ty, tz, rx, ry, rz).finished()) * s.truth[1];
  };
  const geometry::SE3 T_near = moved(0.006, -0.004, 0.008, 0.02, -0.03, 0.01);
  const geometry::SE3 T_wrong = moved(0.05, 0.03, 0.1, 0.3, 0.5, -0.2);
  pipeline::CycleParams p;
  p.budget.cycle_ms = 0.0;  // (no time budget: nothing depends on the clock)
  struct Outcome {
    geometry::SE3 T;
    double evidence = 0.0;
    int used = 0;
  };
  const auto run = [&](bool wrong_first) {
    scene::Scene sc;
    sc.add_camera(scene::Camera{"cam", synth::default_camera(), geometry::SE3()});
    EXPECT_TRUE(sc.add_object("ship", s.model));
    pipeline::VisionCycle cycle(p);
    if (wrong_first) {
      sc.set_pose(0, T_wrong);
      for (int k = 0; k < 3; ++k) cycle.process(sc, std::span(&img, 1), 1.0);
    }
    sc.set_pose(0, T_near);
    // Nothing measured at the other pose is left (a stale line measurement's threshold would
    // still set the edge evidence of an edge left out as side by side at the new pose).
    for (const scene::LineFeature& f : sc.objects()[0].views[0].lines) EXPECT_FALSE(f.measurement.found);
    Outcome o;
    for (int k = 0; k < 3; ++k) o.used = cycle.process(sc, std::span(&img, 1), 2.0).objects[0].lines_used;
    o.T = sc.objects()[0].T_ref_obj;
    o.evidence = sc.objects()[0].evidence;
    return o;
  };
  const Outcome fresh = run(false), after = run(true);
  EXPECT_GT(fresh.used, 5);
  EXPECT_LT((fresh.T.translation() - s.truth[1].translation()).norm(), 0.002);
  EXPECT_EQ(after.used, fresh.used);
  EXPECT_EQ(after.evidence, fresh.evidence);
  EXPECT_LT((after.T.translation() - fresh.T.translation()).norm(), 1e-12);
  EXPECT_LT(geometry::rotation_angle_between(after.T, fresh.T), 1e-12);
}

TEST(ObjectSearch, FindsTheObjectWithoutAPoseAndAllocatesNothingPerFrame) {
  // Issue 10: no start pose. The object is `searching` (the cycle leaves it alone) until the
  // search found it and confirmed it on a second frame; after the first (warm-up) frame neither
  // the search nor the tracking touch the heap.
  const Sequence s = make(&synth::box_cao, 0.55, 10);
  detection::DetectorParams dp;
  auto ts = detection::test::test_templates(*s.model, synth::default_camera(), dp);
  ASSERT_TRUE(ts) << ts.error().to_string();
  pipeline::SingleObjectTracker tracker(s.model, synth::default_camera());
  tracker.enable_search(*ts, pipeline::ObjectSearchParams{}, dp);
  tracker.start_search();
  g_allocations = 0;
  g_counting = true;
  pipeline::FrameResult r = tracker.track(view(s.grey[0]), cview(s.bgr[0]));
  g_counting = false;
  EXPECT_EQ(r.report.status, scene::TrackStatus::kSearching);
  EXPECT_TRUE(r.search.searched);
  EXPECT_EQ(r.report.features_visible, 0) << "a searched object is not tracked by the cycle";
  long allocations = 0;
  int first_tracking = -1;
  for (std::size_t i = 1; i < s.grey.size(); ++i) {
    g_allocations = 0;
    g_counting = true;
    r = tracker.track(view(s.grey[i]), cview(s.bgr[i]));
    g_counting = false;
    // Counted: every search frame, and the tracking frames after the cycle's first one on the
    // object (which sizes the trackers' buffers, the warm-up of the test above).
    if (first_tracking < 0 || static_cast<int>(i) > first_tracking + 1) allocations += g_allocations;
    if (r.report.status == scene::TrackStatus::kTracking && first_tracking < 0) {
      first_tracking = static_cast<int>(i);
      EXPECT_TRUE(r.search.locked);
    }
    if (first_tracking >= 0) {
      EXPECT_EQ(r.report.status, scene::TrackStatus::kTracking) << i;
      EXPECT_LT((r.T_cam_obj.translation() - s.truth[i].translation()).norm(), 0.01) << i;  // (the box: symmetric, translation only)
    }
  }
  EXPECT_EQ(first_tracking, 1) << "found on frame 0, confirmed on frame 1";
  EXPECT_EQ(allocations, 0);
}

TEST(ObjectSearch, AnObjectInHeavySensorNoiseIsAcceptedByTheDetectorsEdgeTest) {
  // Heavy sensor noise: the tracker's windows raise their thresholds above it, and the image
  // confirms fewer samples of the true pose than search.accept_evidence asks. The detector's edge
  // test (gradients summed along the edge, a threshold relative to the frame's noise) verifies it
  // (search.edge_test_evidence). The independent benchmark's box_noise (sigma 12, 1 % salt and
  // pepper) confirms 0.45-0.65 of its samples; our renderer's box keeps more contrast, so the
  // same happens here at sigma 20 and 2 %: measured 0.66-0.73 once tracked; found on frame 0
  // with the edge test, not in 6 frames without (since the detector matches wide gradient
  // plateaus at their centroids, detect.verify.plateau: on frame 3 without).
  Sequence s = make(&synth::box_cao, 0.55, 6);
  cv::RNG rng(12345);
  for (std::size_t i = 0; i < s.bgr.size(); ++i) {
    cv::Mat noise(s.bgr[i].size(), CV_32F), sp(s.bgr[i].size(), CV_32F);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 20.0);
    rng.fill(sp, cv::RNG::UNIFORM, 0.0, 1.0);
    for (int y = 0; y < noise.rows; ++y)
      for (int x = 0; x < noise.cols; ++x) {
        cv::Vec3b& c = s.bgr[i].at<cv::Vec3b>(y, x);
        const float u = sp.at<float>(y, x);
        for (int k = 0; k < 3; ++k)
          c[k] = u < 0.01f ? 0 : u < 0.02f ? 255 : cv::saturate_cast<std::uint8_t>(c[k] + noise.at<float>(y, x));
      }
    cv::cvtColor(s.bgr[i], s.grey[i], cv::COLOR_BGR2GRAY);
  }
  detection::DetectorParams dp;
  auto ts = detection::test::test_templates(*s.model, synth::default_camera(), dp);
  ASSERT_TRUE(ts) << ts.error().to_string();
  auto templates = *ts;
  const auto first_tracking = [&](double edge_test_evidence) {
    pipeline::ObjectSearchParams sp;
    sp.edge_test_evidence = edge_test_evidence;
    sp.consensus_candidates = 0;  // (or the pose several of the detector's candidates end on)
    pipeline::SingleObjectTracker tracker(s.model, synth::default_camera());
    tracker.enable_search(templates, sp, dp);
    tracker.start_search();
    int first = -1;
    for (std::size_t i = 0; i < s.grey.size(); ++i) {
      const pipeline::FrameResult r = tracker.track(view(s.grey[i]), cview(s.bgr[i]));
      if (r.report.status == scene::TrackStatus::kTracking && first < 0) first = static_cast<int>(i);
      if (first >= 0) {
        EXPECT_LT((r.T_cam_obj.translation() - s.truth[i].translation()).norm(), 0.01) << i;
      }
    }
    return first;
  };
  EXPECT_EQ(first_tracking(pipeline::ObjectSearchParams{}.edge_test_evidence), 1) << "found on frame 0, confirmed on frame 1";
  const int without = first_tracking(1.0);
  EXPECT_TRUE(without < 0 || without > 1) << "the evidence alone: found on frame " << without;
}

TEST(ObjectSearch, ALostObjectTurnsToSearchingAfterLostFrames) {
  const Sequence s = make(&synth::box_cao, 0.55, 3);
  detection::DetectorParams dp;
  auto ts = detection::test::test_templates(*s.model, synth::default_camera(), dp);
  ASSERT_TRUE(ts);
  pipeline::ObjectSearchParams sp;
  sp.lost_frames = 3;
  pipeline::SingleObjectTracker tracker(s.model, synth::default_camera());
  tracker.enable_search(*ts, sp, dp);
  tracker.set_pose(s.truth[0]);
  EXPECT_EQ(tracker.track(view(s.grey[0])).report.status, scene::TrackStatus::kTracking);
  const cv::Mat empty(s.grey[0].rows, s.grey[0].cols, CV_8UC1, cv::Scalar(70));
  std::vector<scene::TrackStatus> st;
  for (int i = 0; i < 6; ++i) st.push_back(tracker.track(view(empty)).report.status);
  EXPECT_EQ(st[0], scene::TrackStatus::kLost);
  EXPECT_EQ(st[1], scene::TrackStatus::kLost);
  EXPECT_EQ(st[2], scene::TrackStatus::kSearching) << "the third lost frame in a row";
  for (int i = 3; i < 6; ++i) EXPECT_EQ(st[static_cast<std::size_t>(i)], scene::TrackStatus::kSearching) << i;
}

TEST(ObjectSearch, ARecoveryStartsAtTheLastTrackedPoseNotAtTheDriftedPrediction) {
  // Frames reported `tracking` record their pose; while the object is lost, the pose held (the
  // prediction) may have run off, wrongly measured under occlusion or blur. The search after the
  // loss starts its restarts at the last tracked pose.
  const Sequence s = make(&synth::box_cao, 0.55, 3);
  pipeline::SingleObjectTracker tracker(s.model, synth::default_camera());
  tracker.set_pose(s.truth[0]);
  ASSERT_EQ(tracker.track(view(s.grey[0])).report.status, scene::TrackStatus::kTracking);
  scene::Scene& scene = tracker.scene();
  scene::Object& o = scene.objects()[0];
  ASSERT_TRUE(o.tracked_once);
  const geometry::SE3 tracked = o.T_ref_obj_tracked;
  EXPECT_LT((tracked.translation() - o.T_ref_obj.translation()).norm(), 1e-12);
  const cv::Mat empty(s.grey[0].rows, s.grey[0].cols, CV_8UC1, cv::Scalar(70));
  EXPECT_EQ(tracker.track(view(empty)).report.status, scene::TrackStatus::kLost);
  EXPECT_LT((o.T_ref_obj_tracked.translation() - tracked.translation()).norm(), 1e-12) << "kept while lost";
  // The held pose drifted 8 cm away: the search starts where the object was last tracked.
  o.T_ref_obj = geometry::SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.08, 0.0, 0.0)) * tracked;
  o.status = scene::TrackStatus::kLost;
  pipeline::ObjectSearchParams sp;
  sp.lost_frames = 1;
  ASSERT_TRUE(o.lost_by_image);
  int streak = 0;
  pipeline::LastSeen last;
  ASSERT_EQ(pipeline::search_step(sp, scene, 0, streak, last), pipeline::SearchStep::kStarted);
  const geometry::SE3 expected = scene.cameras()[0].T_ref_cam.inverse() * tracked;
  EXPECT_LT((last.T_cam_obj.translation() - expected.translation()).norm(), 1e-9);
  // A pose set anew (SetPose, a found pose) has not been tracked yet: the held pose is used.
  scene.set_pose(0, o.T_ref_obj);
  EXPECT_FALSE(o.tracked_once);
  o.status = scene::TrackStatus::kLost;
  o.lost_by_image = true;
  streak = 0;
  ASSERT_EQ(pipeline::search_step(sp, scene, 0, streak, last), pipeline::SearchStep::kStarted);
  EXPECT_LT((last.T_cam_obj.translation() - (scene.cameras()[0].T_ref_cam.inverse() * o.T_ref_obj).translation()).norm(),
            1e-9);
}

TEST(ObjectSearch, OnlyFramesLostByTheImageItselfCountTowardsTheSearch) {
  // A frame reported `lost` only because a lost object has not yet confirmed enough of itself
  // (status.return_evidence) is one the tracker still measures near the held pose: it does not
  // count towards search.lost_frames, and it ends a streak.
  const Sequence s = make(&synth::box_cao, 0.55, 1);
  pipeline::SingleObjectTracker tracker(s.model, synth::default_camera());
  tracker.set_pose(s.truth[0]);
  scene::Scene& scene = tracker.scene();
  scene::Object& o = scene.objects()[0];
  pipeline::ObjectSearchParams sp;
  sp.lost_frames = 2;
  int streak = 0;
  pipeline::LastSeen last;
  o.status = scene::TrackStatus::kLost;
  o.lost_by_image = true;
  EXPECT_EQ(pipeline::search_step(sp, scene, 0, streak, last), pipeline::SearchStep::kWaiting);
  o.lost_by_image = false;
  EXPECT_EQ(pipeline::search_step(sp, scene, 0, streak, last), pipeline::SearchStep::kWaiting);
  EXPECT_EQ(streak, 0);
  o.lost_by_image = true;
  EXPECT_EQ(pipeline::search_step(sp, scene, 0, streak, last), pipeline::SearchStep::kWaiting);
  EXPECT_EQ(pipeline::search_step(sp, scene, 0, streak, last), pipeline::SearchStep::kStarted);
  EXPECT_EQ(o.status, scene::TrackStatus::kSearching);
}

/// Feeds `frames` (numbered first_frame, first_frame + 1, ...) to the tracker and returns the
/// number of the first one reported `tracking` (-1: none); from there on every frame must be
/// `tracking` within 1 cm of truth(number). Prints a line per frame, prefixed by `label`.
template <class Truth>
int first_tracking(pipeline::SingleObjectTracker& tracker, const std::vector<cv::Mat>& frames, int first_frame,
                   Truth truth, const std::string& label) {
  int first = -1;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const int i = first_frame + static_cast<int>(k);
    const pipeline::FrameResult fr = tracker.track(view(frames[k]));
    if (fr.report.status == scene::TrackStatus::kTracking && first < 0) first = i;
    if (first >= 0) {
      EXPECT_EQ(fr.report.status, scene::TrackStatus::kTracking) << label << i;
      EXPECT_LT((fr.T_cam_obj.translation() - truth(i).translation()).norm(), 0.01) << label << i;
    }
    std::printf("%s frame %d: %s, search evidence %.2f\n", label.c_str(), i, scene::to_string(fr.report.status),
                fr.search.best_evidence);
  }
  return first;
}

TEST(ObjectSearch, AnObjectThatMovedOnWhileLostIsLookedForWhereItsVelocityTookIt) {
  // The box slides sideways at 6 mm per frame, is tracked for 10 frames, then hidden for 20;
  // it comes back 13 cm further on with its left part behind a board (too little of it for a
  // whole-image detection). The restarts around the last tracked pose do not reach it; those
  // around where its last velocity takes it (search.extrapolate_s) do. (The whole-image search
  // also finds it with search.top_evidence, the detector's best pose taken at a lower share when
  // nothing is verified: off here, so that the restarts are what is tested.)
  auto m = model::parse_cao(synth::box_cao(), "m");
  ASSERT_TRUE(m);
  const auto model = std::make_shared<const model::Model>(std::move(*m));
  const geometry::SE3 T0 = geometry::look_at(0.55, -0.6, 0.75);
  const auto pose = [&](int i) {
    return geometry::SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.06 + 0.006 * i, 0.0, 0.0)) * T0;
  };
  synth::Renderer r(synth::default_camera(), synth::RenderOptions{});
  const auto grey = [&](int i, bool board) {
    const cv::Mat bgr = r.render(*model, pose(i), i);
    cv::Mat g;
    cv::cvtColor(bgr, g, cv::COLOR_BGR2GRAY);
    if (board) {
      const cv::Mat bg = r.render(*model, geometry::SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -10)), i);
      cv::Mat diff, mask;
      cv::absdiff(bgr, bg, diff);
      cv::cvtColor(diff, mask, cv::COLOR_BGR2GRAY);
      const cv::Rect box = cv::boundingRect(mask > 10);
      cv::rectangle(g, cv::Rect(0, 0, box.x + static_cast<int>(0.3 * box.width), g.rows), cv::Scalar(128), cv::FILLED);
    }
    return g;
  };
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 10; ++i) frames.push_back(grey(i, false));
  for (int i = 30; i < 34; ++i) frames.push_back(grey(i, true));
  const cv::Mat empty(frames[0].rows, frames[0].cols, CV_8UC1, cv::Scalar(70));
  detection::DetectorParams dp;
  auto ts = detection::test::test_templates(*model, synth::default_camera(), dp);
  ASSERT_TRUE(ts) << ts.error().to_string();
  const auto templates = *ts;
  const auto run = [&](double extrapolate_s) {
    pipeline::ObjectSearchParams sp;
    sp.extrapolate_s = extrapolate_s;
    sp.top_evidence = sp.accept_evidence;  // the whole-image search at its usual share only
    sp.consensus_candidates = 0;
    pipeline::SingleObjectTracker tracker(model, synth::default_camera());
    tracker.enable_search(templates, sp, dp);
    tracker.set_pose(pose(0));
    for (int i = 0; i < 10; ++i)
      EXPECT_EQ(tracker.track(view(frames[static_cast<std::size_t>(i)])).report.status, scene::TrackStatus::kTracking) << i;
    for (int i = 10; i < 30; ++i) (void)tracker.track(view(empty));
    const std::vector<cv::Mat> back(frames.begin() + 10, frames.end());
    return first_tracking(tracker, back, 30, pose, "[moved on] extrapolate " + std::to_string(extrapolate_s) + " s,");
  };
  EXPECT_EQ(run(pipeline::ObjectSearchParams{}.extrapolate_s), 31) << "found on its return (30), confirmed on 31";
  EXPECT_EQ(run(0.0), -1) << "around the last tracked pose only: not found again";
}

TEST(ObjectSearch, APartlyOccludedObjectIsFoundAgainAroundItsLastPose) {
  // Lost for three empty frames, the box comes back with its left part behind a grey board:
  // the image confirms too little of the model for a whole-image detection (accept_evidence),
  // but a restart around the last tracked pose is accepted at the lower local_accept_evidence
  // (the last pose is a prior), and confirmed on the next frame. The same after 25 empty frames
  // (22 search frames): the restarts are still tried (search.local_frames); when they stop after
  // 10 search frames, the box is not found again. (search.top_evidence, with which the
  // whole-image search finds it too, is off here: the restarts are what is tested.)
  const Sequence s = make(&synth::box_cao, 0.55, 12);
  detection::DetectorParams dp;
  auto ts = detection::test::test_templates(*s.model, synth::default_camera(), dp);
  ASSERT_TRUE(ts) << ts.error().to_string();
  const auto templates = *ts;
  synth::Renderer r(synth::default_camera(), synth::RenderOptions{});
  std::vector<cv::Mat> occluded;
  for (int i = 6; i < 12; ++i) {
    // The object's columns: where the render differs from the background alone.
    const cv::Mat bg = r.render(*s.model, geometry::SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -10)), i);
    cv::Mat diff, mask;
    cv::absdiff(s.bgr[static_cast<std::size_t>(i)], bg, diff);
    cv::cvtColor(diff, mask, cv::COLOR_BGR2GRAY);
    const cv::Rect box = cv::boundingRect(mask > 10);
    cv::Mat g = s.grey[static_cast<std::size_t>(i)].clone();
    cv::rectangle(g, cv::Rect(0, 0, box.x + static_cast<int>(0.3 * box.width), g.rows), cv::Scalar(128), cv::FILLED);
    occluded.push_back(g);
  }
  const cv::Mat empty(s.grey[0].rows, s.grey[0].cols, CV_8UC1, cv::Scalar(70));
  const auto run = [&](double local_accept, int empty_frames = 3,
                       int local_frames = pipeline::ObjectSearchParams{}.local_frames) {
    pipeline::ObjectSearchParams sp;
    sp.local_accept_evidence = local_accept;
    sp.top_evidence = sp.accept_evidence;  // the whole-image search at its usual share only
    sp.consensus_candidates = 0;
    sp.local_frames = local_frames;
    pipeline::SingleObjectTracker tracker(s.model, synth::default_camera());
    tracker.enable_search(templates, sp, dp);
    tracker.set_pose(s.truth[0]);
    for (int i = 0; i < 3; ++i)
      EXPECT_EQ(tracker.track(view(s.grey[static_cast<std::size_t>(i)])).report.status, scene::TrackStatus::kTracking);
    for (int i = 0; i < empty_frames; ++i) (void)tracker.track(view(empty));
    return first_tracking(tracker, occluded, 6, [&](int i) { return s.truth[static_cast<std::size_t>(i)]; },
                          "[occluded return] accept " + std::to_string(local_accept) + ", " +
                              std::to_string(empty_frames) + " empty frames, local frames " +
                              std::to_string(local_frames) + ",");
  };
  EXPECT_EQ(run(pipeline::ObjectSearchParams{}.local_accept_evidence), 7)
      << "accepted around the last pose on its return (frame 6), confirmed on frame 7";
  EXPECT_EQ(run(0.7), -1) << "at the whole-image threshold the occluded box is not accepted";
  const double accept = pipeline::ObjectSearchParams{}.local_accept_evidence;
  EXPECT_EQ(run(accept, 25), 7) << "still looked for around its last pose after 22 search frames";
  EXPECT_EQ(run(accept, 25, 10), -1) << "restarts only on the first 10 search frames: not found again";
}

TEST(VisionCycle, TheOutlinesColoursAreSampledOnlyEveryLeakPeriodFrames) {
  // The silhouette leak feeds only the running mean the search uses after a loss: sampled on
  // the first frame after a pose is set and on every status.leak_period-th frame after it, it
  // is learned as when sampled on every frame, and the poses are the same.
  const Sequence s = make(&synth::sponge_cao, 0.4, 9);
  const auto run = [&](int period, std::vector<int>& sampled, std::vector<geometry::SE3>& poses) {
    pipeline::CycleParams cp;
    cp.status.leak_period = period;
    pipeline::SingleObjectTracker tracker(s.model, synth::default_camera(), cp);
    tracker.set_pose(s.truth[0]);
    for (std::size_t i = 0; i < s.grey.size(); ++i) {
      const pipeline::FrameResult fr = tracker.track(view(s.grey[i]), cview(s.bgr[i]));
      EXPECT_EQ(fr.report.status, scene::TrackStatus::kTracking) << "frame " << i;
      const scene::Object& o = tracker.scene().objects()[0];
      if (o.leak_samples > 0) sampled.push_back(static_cast<int>(i));
      poses.push_back(fr.T_cam_obj);
      if (i == 5 && period > 1) tracker.set_pose(s.truth[6]);  // sampled on its next frame
    }
    return tracker.scene().objects()[0].leak_typical;
  };
  std::vector<int> every, fourth;
  std::vector<geometry::SE3> poses_every, poses_fourth;
  const double typical_every = run(1, every, poses_every);
  const double typical_fourth = run(4, fourth, poses_fourth);
  EXPECT_EQ(every, (std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7, 8}));
  EXPECT_EQ(fourth, (std::vector<int>{0, 4, 6}));
  ASSERT_GE(typical_every, 0.0);
  ASSERT_GE(typical_fourth, 0.0);
  EXPECT_LE(typical_every, 0.1) << "the sponge's outline on the table";
  EXPECT_LE(typical_fourth, 0.1);
  for (std::size_t i = 0; i < 6; ++i)
    EXPECT_LT((poses_every[i].translation() - poses_fourth[i].translation()).norm(), 1e-12) << "frame " << i;
}

TEST(ObjectSearch, AFoundPoseWhoseOutlineLeaksTheObjectsColoursIsRefused) {
  // While tracked, the green sponge's outline separates its colour from the table's: the
  // silhouette leak learned is low. After a loss it comes back on a surface of its own colour
  // (everything around it painted in a darker shade of its mean colour; the outline's edges stay): a
  // pose there leaks the object's colours outside its outline, as one nested in the real object
  // with its edges on texture does, and the search refuses it (status.leak_margin); with the
  // test off (leak_margin 1) the same pose is found and confirmed.
  const Sequence s = make(&synth::sponge_cao, 0.4, 9);
  detection::DetectorParams dp;
  auto ts = detection::test::test_templates(*s.model, synth::default_camera(), dp);
  ASSERT_TRUE(ts) << ts.error().to_string();
  const auto templates = *ts;
  synth::Renderer r(synth::default_camera(), synth::RenderOptions{});
  std::vector<cv::Mat> grey, bgr;
  for (int i = 6; i < 9; ++i) {
    const cv::Mat& im = s.bgr[static_cast<std::size_t>(i)];
    const cv::Mat bg = r.render(*s.model, geometry::SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -10)), i);
    cv::Mat diff, mask;
    cv::absdiff(im, bg, diff);
    cv::cvtColor(diff, mask, cv::COLOR_BGR2GRAY);
    mask = mask > 10;
    const cv::Scalar mean = cv::mean(im, mask);
    cv::Mat c = im.clone();
    c.setTo(0.8 * mean, ~mask);
    cv::Mat g;
    cv::cvtColor(c, g, cv::COLOR_BGR2GRAY);
    bgr.push_back(c);
    grey.push_back(g);
  }
  const cv::Mat empty(s.grey[0].rows, s.grey[0].cols, CV_8UC1, cv::Scalar(70));
  const cv::Mat empty_bgr(s.grey[0].rows, s.grey[0].cols, CV_8UC3, cv::Scalar(70, 70, 70));
  const auto run = [&](double leak_margin) {
    pipeline::CycleParams cp;
    cp.status.leak_margin = leak_margin;
    cp.status.leak_period = 1;  // (the last frame's outline is read below)
    pipeline::SingleObjectTracker tracker(s.model, synth::default_camera(), cp);
    tracker.enable_search(templates, pipeline::ObjectSearchParams{}, dp);
    tracker.set_pose(s.truth[0]);
    for (std::size_t i = 0; i < 3; ++i)
      EXPECT_EQ(tracker.track(view(s.grey[i]), cview(s.bgr[i])).report.status, scene::TrackStatus::kTracking);
    const scene::Object& o = tracker.scene().objects()[0];
    EXPECT_GE(o.leak_typical, 0.0);
    EXPECT_LE(o.leak_typical, 0.1) << "the sponge's outline on the table";
    for (int i = 0; i < 3; ++i) (void)tracker.track(view(empty), cview(empty_bgr));
    int first = -1;
    for (std::size_t k = 0; k < grey.size(); ++k) {
      const pipeline::FrameResult fr = tracker.track(view(grey[k]), cview(bgr[k]));
      if (fr.report.status == scene::TrackStatus::kTracking && first < 0) {
        first = 6 + static_cast<int>(k);
        EXPECT_LT((fr.T_cam_obj.translation() - s.truth[6 + k].translation()).norm(), 0.01);
      }
    }
    // Tracked by the cycle on the last frame: its outline leaks.
    if (first >= 0) {
      EXPECT_GE(o.leak, o.leak_typical + 0.25) << "the found pose leaks";
    }
    return first;
  };
  EXPECT_EQ(run(1.0), 7) << "without the test: found (6) and confirmed (7)";
  EXPECT_EQ(run(pipeline::CycleParams{}.status.leak_margin), -1) << "refused";
}
