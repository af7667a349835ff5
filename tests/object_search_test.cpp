// v4r - robust model-based object tracking. MIT licence.
// Issue 10, finding the object by itself: rendered sequences in which the object starts without
// a pose, leaves the view for 20 frames and comes back at another pose. The tracker (with
// pipeline::ObjectSearch) must lock by frame 10, be `tracking` again within 5 frames of the
// return in >= 95 % of the events, and never say `tracking` on a frame without the object.
#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "../libs/detection/tests/degrees.hpp"
#include "../libs/detection/tests/detection_scenes.hpp"
#include "../libs/detection/tests/test_templates.hpp"
#include "test_objects.hpp"
#include "v4r/detection/symmetry.hpp"
#include "v4r/detection/template_set.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/tracker.hpp"
#include "v4r/synth/conditions.hpp"

using namespace v4r;
namespace sc = v4r::detection::scenes;

namespace {

struct Frame {
  cv::Mat image;
  bool has_object = false;
  geometry::SE3 T;  // truth when has_object
};

/// `visible` frames of a slow motion from a random pose over the detector's view range.
void append_motion(std::vector<Frame>& seq, const model::Model& m, const detection::ViewRange& views,
                   const synth::Renderer& r, std::mt19937& rng, int visible) {
  synth::TrajectorySpec ts;
  ts.frames = visible;
  // Inset by a quarter of each span and 60 px from the border: the slow motion stays in view.
  ts.T0 = sc::random_pose(m, views, r.camera(), rng, 0.25, 60.0);
  ts.translation_amp = 0.01;
  ts.rotation_amp = 0.05;
  ts.depth_amp = 0.02;
  const auto traj = synth::make_trajectory(ts);
  for (int k = 0; k < visible; ++k) {
    const int index = static_cast<int>(seq.size());
    seq.push_back({r.render(m, traj[k], index), true, traj[k]});
  }
}

void append_empty(std::vector<Frame>& seq, const model::Model& m, const synth::Renderer& r, int n) {
  const geometry::SE3 away(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, -5.0));  // behind the camera
  for (int k = 0; k < n; ++k) {
    const int index = static_cast<int>(seq.size());
    seq.push_back({r.render(m, away, index), false, away});
  }
}

/// A test object (test::kObjects, or "section": the ship section) and its templates for `dp`
/// (null pointers on failure).
struct ModelWithTemplates {
  std::shared_ptr<const model::Model> model;
  std::shared_ptr<const detection::TemplateSet> templates;
};
ModelWithTemplates object_with_templates(const std::string& name, const geometry::PinholeCamera& cam,
                                         const detection::DetectorParams& dp) {
  std::string (*cao)() = name == "section" ? &synth::ship_section_cao : nullptr;
  for (const auto& o : test::kObjects)
    if (name == o.name) cao = o.cao;
  if (cao == nullptr) return {};
  auto parsed = model::parse_cao(cao(), name);
  if (!parsed) return {};
  auto model = std::make_shared<const model::Model>(std::move(*parsed));
  auto ts = detection::test::test_templates(*model, cam, dp);
  if (!ts) return {};
  return {model, *ts};
}
/// `v4r track` without a pose on a still object: the search given the same colour image twice
/// (found on the first frame, confirmed on the second); the second frame's result.
pipeline::FrameResult search_still_image(const std::shared_ptr<const model::Model>& model,
                                         const std::shared_ptr<const detection::TemplateSet>& templates,
                                         const geometry::PinholeCamera& cam, const pipeline::ObjectSearchParams& sp,
                                         const detection::DetectorParams& dp, const cv::Mat& bgr) {
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  pipeline::SingleObjectTracker tracker(model, cam);
  tracker.enable_search(templates, sp, dp);
  tracker.start_search();
  pipeline::FrameResult fr;
  for (int rep = 0; rep < 2; ++rep) fr = tracker.track(io::as_view(grey), io::as_colour_view(bgr));
  return fr;
}
ModelWithTemplates box_with_templates(const geometry::PinholeCamera& cam, const detection::DetectorParams& dp) {
  return object_with_templates("box", cam, dp);
}

/// What the search made of still images under each of several settings.
struct StillTally {
  int found = 0;  ///< `tracking` within 5 cm / 5 deg of the truth (modulo the symmetries)
  int twins = 0;  ///< `tracking` turned 170 deg or more from it (a near-symmetric twin)
  int wrong = 0;  ///< `tracking` elsewhere
};
/// `images` of the detection evaluation's renders of test object `name` under scene `s` (its
/// random poses, seeds and default view range), each given to search_still_image once per setting
/// in `sp`; one tally per setting, in `tally` (same size). `dps`: the detector's settings, one
/// per setting (the same view range; empty: the defaults). `first`: the evaluation's images from
/// that one on. False when the object cannot be built.
bool search_evaluation_renders(const std::string& name, sc::Scene s, int images,
                               std::span<const pipeline::ObjectSearchParams> sp, std::span<StillTally> tally,
                               std::span<const detection::DetectorParams> dps = {}, int first = 0) {
  const geometry::PinholeCamera cam = synth::default_camera();
  const detection::DetectorParams dp;  // default view range
  const auto [model, templates] = object_with_templates(name, cam, dp);
  if (!model || !templates) return false;
  const auto sym = detection::model_symmetries(*model);
  std::mt19937 rng(1000u + static_cast<std::uint32_t>(s) * 77u);  // as the evaluation seeds each scene
  for (int k = 0; k < first + images; ++k) {
    const geometry::SE3 T = sc::random_pose(*model, dp.views, cam, rng);
    if (k < first) continue;  // (the evaluation's images from `first` on)
    const cv::Mat img = sc::render_scene(*model, T, cam, s, 100u + static_cast<std::uint32_t>(k));
    for (std::size_t i = 0; i < sp.size(); ++i) {
      const pipeline::FrameResult fr = search_still_image(model, templates, cam, sp[i], dps.empty() ? dp : dps[i], img);
      if (fr.report.status != scene::TrackStatus::kTracking) continue;
      const auto e = detection::symmetric_pose_error(fr.T_cam_obj, T, sym);
      if (e.translation <= 0.05 && e.rotation <= 5.0 * kDeg) ++tally[i].found;
      else if (e.rotation >= 170.0 * kDeg) ++tally[i].twins;
      else ++tally[i].wrong;
    }
  }
  return true;
}

}  // namespace

TEST(ObjectSearch, FindsTheObjectWithoutAPoseAndAgainAfterTwentyFramesOutOfView) {
  const geometry::PinholeCamera cam = synth::default_camera();
  int events = 0, recovered = 0, empty_tracking = 0, empty_frames = 0, late_start = 0;
  std::vector<double> search_ms;
  for (const char* name : {"box", "flange"}) {
    detection::DetectorParams dp;  // default view range
    const auto [model, templates] = object_with_templates(name, cam, dp);
    ASSERT_TRUE(model && templates) << name;
    const auto sym = detection::model_symmetries(*model);
    for (std::uint32_t seed = 1; seed <= 3; ++seed) {
      synth::RenderOptions ro;
      if (seed == 3) ro = synth::options_for(synth::Condition::kClutter, ro);
      ro.seed = seed;
      ro.cycle_frames = 2;
      synth::Renderer r(cam, ro);
      std::mt19937 rng(1000u * seed + static_cast<std::uint32_t>(model->lines().size()));
      // 15 frames in view (no pose given), 20 out of view, 15 back at another pose, 20 out, 15 back.
      std::vector<Frame> seq;
      std::vector<int> returns;
      append_motion(seq, *model, dp.views, r, rng, 15);
      for (int k = 0; k < 2; ++k) {
        append_empty(seq, *model, r, 20);
        returns.push_back(static_cast<int>(seq.size()));
        append_motion(seq, *model, dp.views, r, rng, 15);
      }
      pipeline::SingleObjectTracker tracker(model, cam);
      tracker.enable_search(templates, pipeline::ObjectSearchParams{}, dp);
      tracker.start_search();
      std::vector<scene::TrackStatus> status;
      std::vector<geometry::SE3> pose;
      for (std::size_t i = 0; i < seq.size(); ++i) {
        cv::Mat grey;
        cv::cvtColor(seq[i].image, grey, cv::COLOR_BGR2GRAY);
        const pipeline::FrameResult fr = tracker.track(io::as_view(grey), io::as_colour_view(seq[i].image));
        status.push_back(fr.report.status);
        pose.push_back(fr.T_cam_obj);
        if (fr.search.searched) search_ms.push_back(fr.search.search_ms);
        if (std::getenv("V4R_SEARCH_DEBUG") && seq[i].has_object) {
          const auto e = detection::symmetric_pose_error(fr.T_cam_obj, seq[i].T, sym);
          const auto elev = [&](const geometry::SE3& T) {
            const Eigen::Vector3d eye = T.inverse().translation() - detection::model_extent(*model).centre;
            return std::asin(eye.z() / eye.norm()) / kDeg;
          };
          std::printf("  %s %u frame %zu: %s tried %d best %.2f found %d locked %d ev %.2f err %.1f mm %.1f deg el %.1f truth el %.1f d %.3f truth d %.3f\n", name,
                      seed, i, scene::to_string(fr.report.status), fr.search.tried, fr.search.best_evidence,
                      fr.search.found, fr.search.locked, fr.report.evidence, 1e3 * e.translation, e.rotation / kDeg,
                      elev(fr.T_cam_obj), elev(seq[i].T), fr.T_cam_obj.translation().norm(), seq[i].T.translation().norm());
        }
        if (!seq[i].has_object) {
          ++empty_frames;
          if (fr.report.status == scene::TrackStatus::kTracking) ++empty_tracking;
        }
      }
      // An event: the object appears (frame 0, each return); recovered when `tracking` within
      // 5 frames at a pose within 2 cm / 5 degrees of the truth (modulo the model's symmetries).
      const auto first_tracking = [&](int from) {
        for (int i = from; i < static_cast<int>(seq.size()) && seq[static_cast<std::size_t>(i)].has_object; ++i)
          if (status[static_cast<std::size_t>(i)] == scene::TrackStatus::kTracking) return i;
        return -1;
      };
      std::vector<int> starts = {0};
      starts.insert(starts.end(), returns.begin(), returns.end());
      for (const int s : starts) {
        const int f = first_tracking(s);
        bool ok = false;
        double et = -1, er = -1;
        if (f >= 0) {
          const auto e = detection::symmetric_pose_error(pose[static_cast<std::size_t>(f)],
                                                         seq[static_cast<std::size_t>(f)].T, sym);
          et = e.translation;
          er = e.rotation;
          ok = f - s < (s == 0 ? 11 : 5) && et <= 0.02 && er <= 5.0 * kDeg;
        }
        std::printf("[search] %s seed %u: object from frame %d, tracking at %d (%.1f mm, %.2f deg) %s\n", name, seed,
                    s, f, 1e3 * et, er / kDeg, ok ? "ok" : "MISSED");
        if (s == 0) {
          late_start += ok ? 0 : 1;
        } else {
          ++events;
          recovered += ok ? 1 : 0;
        }
      }
    }
  }
  std::sort(search_ms.begin(), search_ms.end());
  if (!search_ms.empty())
    std::printf("[search] %zu search frames: median %.1f ms, p95 %.1f ms\n", search_ms.size(),
                search_ms[search_ms.size() / 2], search_ms[search_ms.size() * 95 / 100]);
  std::printf("[search] recovered %d of %d returns; %d of %d object-free frames said tracking\n", recovered, events,
              empty_tracking, empty_frames);
  EXPECT_EQ(late_start, 0) << "sequences not locked by frame 10 from no pose";
  // The issue asks for >= 95 % of returns: all 12.
  EXPECT_GE(recovered, events) << "of " << events << " returns";
  EXPECT_EQ(empty_tracking, 0) << "of " << empty_frames << " object-free frames";
}

TEST(ObjectSearch, NeverTracksOnObjectFreeImages) {
  // Clutter backgrounds and no object at all: searched on every frame, never `tracking`.
  const geometry::PinholeCamera cam = synth::default_camera();
  const detection::DetectorParams dp;  // default view range
  const auto [model, templates] = box_with_templates(cam, dp);
  ASSERT_TRUE(model && templates);
  pipeline::SingleObjectTracker tracker(model, cam);
  tracker.enable_search(templates, pipeline::ObjectSearchParams{}, dp);
  tracker.start_search();
  std::mt19937 rng(77u);
  int tracking = 0, searched = 0, candidates = 0;
  for (int i = 0; i < 30; ++i) {
    const cv::Mat img = sc::empty_scene(cam, 0, "", rng);
    cv::Mat grey;
    cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
    // Each image twice in a row: a false candidate gets its second frame to be confirmed on.
    for (int rep = 0; rep < 2; ++rep) {
      const pipeline::FrameResult fr = tracker.track(io::as_view(grey), io::as_colour_view(img));
      tracking += fr.report.status == scene::TrackStatus::kTracking ? 1 : 0;
      searched += fr.search.searched ? 1 : 0;
      candidates += fr.search.found ? 1 : 0;
      EXPECT_EQ(fr.report.status, scene::TrackStatus::kSearching) << "image " << i;
    }
  }
  std::printf("[search] object-free: %d frames searched, %d candidates, %d tracking\n", searched, candidates, tracking);
  EXPECT_EQ(searched, 60);
  EXPECT_EQ(tracking, 0);
}

TEST(ObjectSearch, AStripePrintedOnTheBoxDoesNotKeepTheSearchFromIt) {
  // A dark stripe across the box's top face, parallel to an edge of it (the development
  // benchmark's box has one): the detector's alignment can pull a near-true template onto it, a
  // pose farther away whose edge lies on the stripe. The search also refines each hypothesis from
  // its template's pose (search.template_starts) and reaches the box.
  const geometry::PinholeCamera cam = synth::default_camera();
  const detection::DetectorParams dp;  // default view range
  const auto [model, templates] = box_with_templates(cam, dp);
  ASSERT_TRUE(model && templates);
  const auto sym = detection::model_symmetries(*model);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const auto& j : model->junctions()) {
    lo = lo.cwiseMin(j.p);
    hi = hi.cwiseMax(j.p);
  }
  int found[2] = {0, 0}, gross[2] = {0, 0};  // locks within 2 cm / 5 deg, locks more than 20 deg off
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    synth::RenderOptions ro;
    ro.seed = seed;
    synth::Renderer r(cam, ro);
    std::mt19937 rng(500u + seed);
    const geometry::SE3 T = sc::random_pose(*model, dp.views, cam, rng, 0.25, 60.0);
    r.set_scene_reference(*model, {T, T});
    cv::Mat img = r.render(*model, T, 0);
    // The stripe: across the top face, parallel to its x edges, 12 % of its width in.
    const double y = hi.y() - 0.12 * (hi.y() - lo.y());
    const Eigen::Vector3d a(lo.x(), y, hi.z()), b(hi.x(), y, hi.z());
    const Eigen::Vector2d pa = cam.project(T * a), pb = cam.project(T * b);
    cv::line(img, cv::Point2d(pa.x(), pa.y()), cv::Point2d(pb.x(), pb.y()), cv::Scalar(30, 30, 30), 4, cv::LINE_AA);
    cv::Mat grey;
    cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
    for (const bool starts : {false, true}) {
      pipeline::ObjectSearchParams sp;
      sp.template_starts = starts;
      pipeline::SingleObjectTracker tracker(model, cam);
      tracker.enable_search(templates, sp, dp);
      tracker.start_search();
      for (int i = 0; i < 4; ++i) {
        const pipeline::FrameResult fr = tracker.track(io::as_view(grey), io::as_colour_view(img));
        if (fr.report.status != scene::TrackStatus::kTracking) continue;
        const auto e = detection::symmetric_pose_error(fr.T_cam_obj, T, sym);
        if (e.translation <= 0.02 && e.rotation <= 5.0 * kDeg) ++found[starts ? 1 : 0];
        if (e.rotation > 20.0 * kDeg) ++gross[starts ? 1 : 0];
        break;
      }
    }
  }
  std::printf("[stripe] found %d of 20 without template starts (%d locks > 20 deg off), %d with (%d)\n", found[0], gross[0],
              found[1], gross[1]);
  // Measured: 17 of 20 without (one lock 88 degrees off), 18 with (none); since the tracking
  // cycle leaves a pose the image confirms at samples.doubt_evidence to its line solve (the
  // confirming frames), 19 without (none off) and 20 with. The stripe also makes both settle 8..23
  // mm or 2..10 degrees off on other poses: left for later.
  EXPECT_GT(found[1], found[0]);
  EXPECT_GE(found[1], 17) << "of 20";
  EXPECT_EQ(gross[1], 0);
}

TEST(ObjectSearch, APartlyHiddenObjectThatStandsOutIsFoundOnAStillImage) {
  // A third of the object hidden by the renderer's occluder: its hidden edges confirm nothing, so
  // the tracker's evidence stays under search.accept_evidence and the detector's edge score under
  // its accept_score. The detector's colour verdicts (its colour test, its stand-out verdict: the
  // outline parts its colours from the surroundings) let the search accept it at
  // search.stand_out_evidence, when the tracker's refinement keeps the pose. Each image is given
  // twice (a still object: found, then confirmed).
  std::array<pipeline::ObjectSearchParams, 2> sp;  // [0]: stand-out evidence off, [1]: on
  sp[0].stand_out_evidence = 1.0;
  sp[0].top_evidence = sp[0].accept_evidence;  // (with nothing verified the best pose would be taken instead)
  sp[0].consensus_candidates = 0;               // (or a pose several of the detector's candidates end on)
  std::array<StillTally, 2> t;
  constexpr int kImages = 12;
  for (const char* name : {"ship", "flange"})
    ASSERT_TRUE(search_evaluation_renders(name, sc::Scene::kOcclusion, kImages, sp, t)) << name;
  const int images = 2 * kImages;
  std::printf("[occluded] %d images: found %d (%d wrong) without the stand-out evidence, %d (%d wrong) with\n", images,
              t[0].found, t[0].wrong + t[0].twins, t[1].found, t[1].wrong + t[1].twins);
  EXPECT_GE(t[1].found, t[0].found + images / 5);
  EXPECT_GE(t[1].found, images * 2 / 3);
  EXPECT_LE(t[1].wrong + t[1].twins, t[0].wrong + t[0].twins + 1);
}

TEST(ObjectSearch, TheSectionIsNotFoundTurnedHalfRound) {
  // The ship section turned half round about its plate's normal is its near-symmetric twin: the
  // walls swap places, 12 and 10 cm high. The tracker's evidence hardly tells the two apart, and
  // without the detector's twin test on its chosen pose the search confirmed the twin on 4 of these
  // 22 noisy renders (the detection evaluation's noise scenes), where the detector alone is right.
  constexpr int kImages = 22;
  const std::array<pipeline::ObjectSearchParams, 1> sp{};
  std::array<StillTally, 1> t;
  ASSERT_TRUE(search_evaluation_renders("section", sc::Scene::kNoise, kImages, sp, t));
  std::printf("[section, noise] %d images: found %d, %d twins, %d other wrong\n", kImages, t[0].found, t[0].twins,
              t[0].wrong);
  EXPECT_LE(t[0].twins, 1);
  EXPECT_GE(t[0].found, kImages - 2);
  EXPECT_LE(t[0].wrong, 1);
}

TEST(ObjectSearch, AFoundPoseIsConfirmedOnABlurredStillImage) {
  // Blurred renders of thin plates (the ship mockup and the section; the detection evaluation's
  // blur scenes), each given twice. Tracked again on the second frame, a found pose may slide 4-5
  // cm along a direction the blur leaves weak, past search.confirm_translation, while that
  // frame's own search finds the same pose again (search.refound_factor: 2 of these ship
  // renders); or the tracker keeps it but uses fewer than half its features, `degraded`
  // (search.confirm_degraded: 1 section render). Without the two rules such poses are searched
  // for again on every frame of a still image.
  std::array<pipeline::ObjectSearchParams, 2> sp;  // [0]: both rules off, [1]: on (the defaults)
  sp[0].refound_factor = 1.0;
  sp[0].confirm_degraded = 0.0;
  std::array<StillTally, 2> t;
  constexpr int kImages = 40;
  for (const char* name : {"ship", "section"})
    ASSERT_TRUE(search_evaluation_renders(name, sc::Scene::kBlur, kImages, sp, t)) << name;
  std::printf("[ship and section, blur] %d images: found %d (%d wrong) without the two rules, %d (%d wrong) with\n",
              2 * kImages, t[0].found, t[0].wrong + t[0].twins, t[1].found, t[1].wrong + t[1].twins);
  EXPECT_GE(t[1].found, t[0].found + 3);
  EXPECT_LE(t[1].wrong + t[1].twins, t[0].wrong + t[0].twins);
}

TEST(ObjectSearch, ANearSymmetricTwinIsToldOnABlurredStillImage) {
  // Blurred renders of the section (the detection evaluation's blur scenes), each given twice. The
  // section and its twin (turned half round) differ only in their walls' tops; under motion blur
  // both poses' distinctive samples find a gradient on the smeared edges, and the share test
  // leaves the pair undecided. Where the samples lie from the edges' centres still tells them
  // (detect.verify.twin_residual_margin), once the found pose is aligned as its twin is.
  std::array<pipeline::ObjectSearchParams, 2> sp;
  std::array<detection::DetectorParams, 2> dp;  // [0]: the residual test off, [1]: on (the default)
  dp[0].verify.twin_residual_margin = 0.0;
  std::array<StillTally, 2> t;
  constexpr int kImages = 40;
  ASSERT_TRUE(search_evaluation_renders("section", sc::Scene::kBlur, kImages, sp, t, dp));
  std::printf("[section, blur] %d images: found %d (%d twins, %d wrong) without the residual test, %d (%d twins, %d wrong) with\n",
              kImages, t[0].found, t[0].twins, t[0].wrong, t[1].found, t[1].twins, t[1].wrong);
  EXPECT_GE(t[1].found, t[0].found + 2);
  EXPECT_LT(t[1].twins, t[0].twins);
  EXPECT_LE(t[1].wrong, t[0].wrong);
}

TEST(ObjectSearch, APartlyHiddenSectionIsFoundWhenNothingIsVerified) {
  // The section, 30 % hidden (the detection evaluation's occlusion scenes), each image given
  // twice. Its grey plates' shaded faces are about as dark as the background, so its outline
  // leaks (0.38-0.68) and the detector verifies nothing by colour; the tracker confirms 0.62-0.65
  // of the projected model's samples, under the usual 0.7. With nothing verified, the
  // detector's best-scoring pose is accepted at search.top_evidence (0.6) when the tracker keeps
  // it in place, and confirmed on the next frame at the usual share.
  std::array<pipeline::ObjectSearchParams, 2> sp;  // [0]: off, [1]: the default
  sp[0].top_evidence = sp[0].accept_evidence;
  for (auto& p : sp) p.consensus_candidates = 0;  // (or a pose several of the detector's candidates end on)
  std::array<StillTally, 2> t;
  constexpr int kImages = 40;
  ASSERT_TRUE(search_evaluation_renders("section", sc::Scene::kOcclusion, kImages, sp, t));
  std::printf("[section, 30 %% occluded] %d images: found %d (%d wrong) without, %d (%d wrong) with\n", kImages, t[0].found,
              t[0].wrong + t[0].twins, t[1].found, t[1].wrong + t[1].twins);
  EXPECT_GE(t[1].found, t[0].found + 3);
  EXPECT_LE(t[1].wrong + t[1].twins, t[0].wrong + t[0].twins);
}

TEST(ObjectSearch, APartlyHiddenSectionIsFoundWhereTheDetectorsCandidatesMeet) {
  // The section, 30 % hidden (the detection evaluation's occlusion scenes), each image given
  // twice. A third of its edges hidden, the tracker holds the right pose at 0.55-0.6 of its
  // samples, under every share a single start is accepted at; but several of the detector's
  // candidates, some 5-15 degrees off, end on that very pose. With nothing accepted on a frame, a
  // pose held at search.consensus_evidence that starts from search.consensus_candidates candidates
  // end on is accepted, and confirmed on the next frame at that share.
  std::array<pipeline::ObjectSearchParams, 2> sp;  // [0]: off, [1]: the default
  sp[0].consensus_candidates = 0;
  std::array<StillTally, 2> t;
  constexpr int kFirst = 40, kImages = 40;  // (the first 40 gain nothing; three of the next 40 do)
  ASSERT_TRUE(search_evaluation_renders("section", sc::Scene::kOcclusion, kImages, sp, t, {}, kFirst));
  std::printf("[section, 30 %% occluded] %d images: found %d (%d wrong) without, %d (%d wrong) with\n", kImages, t[0].found,
              t[0].wrong + t[0].twins, t[1].found, t[1].wrong + t[1].twins);
  EXPECT_GE(t[1].found, t[0].found + 2);
  EXPECT_LE(t[1].wrong + t[1].twins, t[0].wrong + t[0].twins);
}

TEST(ObjectSearch, APoseFittedToClutterDoesNotOutrankTheObject) {
  // The box on the renderer's clutter (the detection evaluation's clutter scenes), each image given
  // twice. A pose fitted to the clutter's straight lines, larger than the box, can confirm more edge
  // samples than the box itself at a far lower share (0.76 against 0.99 on one of these); ranked
  // by samples times share squared it won, with the share to the fourth power
  // (search.rank_evidence_power) it does not.
  std::array<pipeline::ObjectSearchParams, 2> sp;  // [0]: power 2, [1]: the default
  sp[0].rank_evidence_power = 2.0;
  std::array<StillTally, 2> t;
  constexpr int kImages = 40;
  ASSERT_TRUE(search_evaluation_renders("box", sc::Scene::kClutter, kImages, sp, t));
  std::printf("[box, clutter] %d images: found %d (%d wrong) with the share squared, %d (%d wrong) to the fourth\n", kImages,
              t[0].found, t[0].wrong + t[0].twins, t[1].found, t[1].wrong + t[1].twins);
  EXPECT_GE(t[1].found, t[0].found + 2);
  EXPECT_GE(t[1].found, kImages * 19 / 20);
  EXPECT_LE(t[1].wrong + t[1].twins, t[0].wrong + t[0].twins);
}
