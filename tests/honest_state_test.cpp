// v4r - robust model-based object tracking. MIT licence.
// An honest state (issue 9), on our own renders: the reported sigma matches the real error, an
// object out of view is never `tracking` and its sigma grows, an object at rest is reported at
// rest. Runs start from a pose perturbed by 1 cm / 3 degrees. (The independent benchmark's
// figures are in the note; these tests guard the behaviour.)
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "v4r/geometry/look_at.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/tracker.hpp"
#include "v4r/synth/conditions.hpp"
#include "v4r/synth/renderer.hpp"

#include "test_objects.hpp"

using namespace v4r;

namespace {

using test::kObjects;
using test::ObjectCase;

std::shared_ptr<const model::Model> load(const ObjectCase& o) {
  auto m = model::parse_cao(o.cao(), o.name);
  EXPECT_TRUE(m.has_value());
  return std::make_shared<const model::Model>(std::move(*m));
}

geometry::SE3 perturbed(const geometry::SE3& T) {
  geometry::Vector6d d;
  d << 0.006, -0.005, 0.006, 0.03, -0.025, 0.03;  // 9.8 mm, 2.9 degrees
  return geometry::SE3::exp(d) * T;
}

struct Row {
  geometry::SE3 truth, est;
  geometry::Matrix6d cov;
  scene::TrackStatus status;
};

/// Tracks `truth` rendered with `ro`; frames whose truth is empty (nullopt) render the
/// background only (the object out of view).
std::vector<Row> run(const ObjectCase& oc, const std::vector<geometry::SE3>& truth, synth::RenderOptions ro,
                     const std::vector<bool>& absent = {}, const pipeline::CycleParams& cp = {}) {
  auto model = load(oc);
  const geometry::PinholeCamera cam = synth::default_camera();
  ro.colour = true;
  ro.cycle_frames = static_cast<int>(truth.size());
  synth::Renderer renderer(cam, ro);
  renderer.set_scene_reference(*model, truth);
  pipeline::SingleObjectTracker tracker(model, cam, cp);
  tracker.set_pose(perturbed(truth[0]));
  std::vector<Row> rows;
  cv::Mat grey;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const bool gone = i < absent.size() && absent[i];
    // Out of view: the object is rendered 2 m to the side, the image shows the background.
    geometry::SE3 shown = truth[i];
    if (gone) shown.set_translation(shown.translation() + Eigen::Vector3d(2.0, 0.0, 0.0));
    const cv::Mat bgr = renderer.render(*model, shown, static_cast<int>(i), i > 0 && !gone ? &truth[i - 1] : nullptr);
    cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
    const auto r = tracker.track(io::as_view(grey), io::as_colour_view(bgr));
    rows.push_back({truth[i], r.T_cam_obj, r.covariance, r.report.status});
  }
  return rows;
}

std::vector<geometry::SE3> moving(const ObjectCase& oc, synth::Condition c, int frames) {
  synth::TrajectorySpec spec;
  spec.frames = frames;
  spec.T0 = geometry::look_at(oc.distance, -0.6, 0.75);
  return synth::make_trajectory(synth::trajectory_spec_for(c, spec));
}

}  // namespace

// Translation error per camera axis over the reported sigma, every frame from the 5th that is
// reported tracking or degraded, per condition (every one of our renders' conditions) over the
// objects: within 3 sigma on 90 % of axis-frames and a median |e|/sigma in 0.4..1.2 (a calibrated
// Gaussian gives 0.67). Under motion blur the renderer exposes frame i from pose i-1 to pose i,
// so the image shows the object half a frame before the frame's pose: the tracker is told so
// (filter.image_delay) and reports the pose at the frame's time. (The flange in clutter, from
// this test's start, is lost without the search and adds no rows there.)
TEST(HonestState, ReportedSigmaMatchesTheTranslationErrorUnderEveryCondition) {
  std::size_t total = 0;
  for (synth::Condition c : synth::all_conditions()) {
    const synth::RenderOptions ro = synth::options_for(c);
    pipeline::CycleParams cp;
    if (ro.blur_samples > 1) cp.image_delay_s = 0.5 * ro.blur_exposure * cp.frame_interval_s;
    std::vector<double> z;
    for (const ObjectCase& oc : kObjects) {
      const auto rows = run(oc, moving(oc, c, 60), ro, {}, cp);
      std::vector<double> zo;
      for (std::size_t i = 5; i < rows.size(); ++i) {
        const Row& r = rows[i];
        if (r.status != scene::TrackStatus::kTracking && r.status != scene::TrackStatus::kDegraded) continue;
        for (int a = 0; a < 3; ++a) {
          const double s = std::sqrt(r.cov(a, a));
          ASSERT_GT(s, 0.0) << oc.name << " " << synth::condition_name(c) << " frame " << i;
          zo.push_back(std::abs(r.est.translation()[a] - r.truth.translation()[a]) / s);
        }
      }
      std::sort(zo.begin(), zo.end());
      if (!zo.empty())
        fmt::print("[{} {}] axis-frames {} median |e|/sigma {:.2f}\n", oc.name, synth::condition_name(c), zo.size(),
                   zo[zo.size() / 2]);
      z.insert(z.end(), zo.begin(), zo.end());
    }
    ASSERT_GT(z.size(), 300u) << synth::condition_name(c);
    total += z.size();
    std::sort(z.begin(), z.end());
    const double within3 =
        static_cast<double>(std::count_if(z.begin(), z.end(), [](double v) { return v <= 3.0; })) / z.size();
    const double median = z[z.size() / 2];
    fmt::print("{}: {} axis-frames, within 3 sigma {:.3f}, median |e|/sigma {:.3f}\n", synth::condition_name(c), z.size(),
               within3, median);
    EXPECT_GE(within3, 0.90) << synth::condition_name(c);
    EXPECT_GE(median, 0.4) << synth::condition_name(c);
    EXPECT_LE(median, 1.2) << synth::condition_name(c);
  }
  EXPECT_GT(total, 4000u);
}

// Under motion blur that ends at the frame's pose, a tracker not told of it reports the pose of
// the exposure's middle: half a frame behind, far outside its sigma. Told (filter.image_delay),
// it moves the pose on to the frame's time with its velocity.
TEST(HonestState, AnImageDelayMovesThePoseOnToTheFramesTime) {
  const ObjectCase& oc = kObjects[0];
  const synth::RenderOptions ro = synth::options_for(synth::Condition::kBlur);
  const auto truth = moving(oc, synth::Condition::kBlur, 40);
  const auto median_error = [&](double delay_s) {
    pipeline::CycleParams cp;
    cp.image_delay_s = delay_s;
    const auto rows = run(oc, truth, ro, {}, cp);
    std::vector<double> e;
    for (std::size_t i = 5; i < rows.size(); ++i)
      e.push_back((rows[i].est.translation() - rows[i].truth.translation()).norm());
    std::sort(e.begin(), e.end());
    return e[e.size() / 2];
  };
  double step = 0.0;
  for (std::size_t i = 5; i < truth.size(); ++i) step += (truth[i].translation() - truth[i - 1].translation()).norm();
  step /= static_cast<double>(truth.size() - 5);
  const double half_frame = 0.5 * pipeline::CycleParams{}.frame_interval_s;
  const double without = median_error(0.0), with = median_error(half_frame);
  fmt::print("mean step {:.2f} mm; median error without the delay {:.2f} mm, with {:.2f} mm\n", 1e3 * step, 1e3 * without,
             1e3 * with);
  EXPECT_GT(without, 0.3 * step) << "half a frame behind";
  EXPECT_LT(with, 0.5 * without);
}

// The object leaves the view for 20 frames: none of them says tracking, and the sigma grows past
// 1 cm; it returns where it left and is tracked again.
TEST(HonestState, ObjectOutOfViewIsNeverTrackingAndItsSigmaGrows) {
  for (const ObjectCase& oc : kObjects) {
    const int frames = 70;
    std::vector<geometry::SE3> truth(frames, geometry::look_at(oc.distance, -0.6, 0.75));
    std::vector<bool> absent(frames, false);
    for (int i = 30; i < 50; ++i) absent[static_cast<std::size_t>(i)] = true;
    const auto rows = run(oc, truth, synth::options_for(synth::Condition::kNoise), absent);
    for (int i = 5; i < 30; ++i)
      EXPECT_EQ(rows[static_cast<std::size_t>(i)].status, scene::TrackStatus::kTracking) << oc.name << " frame " << i;
    double sigma_end = 0.0;
    for (int i = 30; i < 50; ++i) {
      const Row& r = rows[static_cast<std::size_t>(i)];
      EXPECT_NE(r.status, scene::TrackStatus::kTracking) << oc.name << " frame " << i << " (object out of view)";
      sigma_end = std::sqrt(r.cov.topLeftCorner<3, 3>().diagonal().maxCoeff());
    }
    fmt::print("[{}] sigma after 20 frames out of view: {:.1f} mm\n", oc.name, sigma_end * 1e3);
    EXPECT_GT(sigma_end, 0.01) << oc.name;
  }
}

// At rest under sensor noise only: translation std <= 0.1 mm per axis and rotation std <= 0.02
// degrees after frame 10, never lost.
TEST(HonestState, ObjectAtRestIsReportedAtRest) {
  for (const ObjectCase& oc : kObjects) {
    const int frames = 120;
    const std::vector<geometry::SE3> truth(frames, geometry::look_at(oc.distance, -0.6, 0.75));
    synth::RenderOptions ro = synth::options_for(synth::Condition::kRegular);
    ro.noise_sigma = 3.0;
    const auto rows = run(oc, truth, ro);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    int n = 0, lost = 0;
    for (int i = 10; i < frames; ++i, ++n) mean += rows[static_cast<std::size_t>(i)].est.translation();
    mean /= n;
    Eigen::Vector3d var = Eigen::Vector3d::Zero();
    double rot2 = 0.0;
    const geometry::SE3& ref = rows[static_cast<std::size_t>(frames - 1)].est;
    for (int i = 10; i < frames; ++i) {
      const Row& r = rows[static_cast<std::size_t>(i)];
      var += (r.est.translation() - mean).cwiseAbs2();
      const double a = geometry::rotation_angle_between(r.est, ref);
      rot2 += a * a;
      lost += r.status == scene::TrackStatus::kLost ? 1 : 0;
    }
    const double t_std = std::sqrt((var / n).maxCoeff());
    const double r_std = std::sqrt(rot2 / n) * 180.0 / M_PI;
    fmt::print("[{}] at rest: translation std {:.4f} mm (largest axis), rotation std {:.4f} deg, lost {}\n", oc.name,
               t_std * 1e3, r_std, lost);
    EXPECT_LE(t_std, 1e-4) << oc.name;
    EXPECT_LE(r_std, 0.02) << oc.name;
    EXPECT_EQ(lost, 0) << oc.name;
  }
}
