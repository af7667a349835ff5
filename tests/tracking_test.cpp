// v4r - robust model-based object tracking. MIT licence.
// End-to-end: rendered sequences with ground truth, tracked through the whole vision cycle.
#include <memory>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "v4r/geometry/look_at.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/evaluation.hpp"
#include "v4r/pipeline/tracker.hpp"
#include "v4r/synth/renderer.hpp"

using namespace v4r;

namespace {

struct SequenceCase {
  const char* name;
  std::string (*cao)();
  double distance, azimuth, elevation;
  double speed;
};

void PrintTo(const SequenceCase& c, std::ostream* os) { *os << c.name; }

struct SequenceResult {
  pipeline::AccuracyStats acc;
  int lost = 0;
  double mean_used = 0;
};

SequenceResult run_sequence(const SequenceCase& c, int frames = 120) {
  auto m = model::parse_cao(c.cao(), c.name);
  EXPECT_TRUE(m.has_value()) << (m ? "" : m.error().to_string());
  auto model = std::make_shared<const model::Model>(std::move(*m));
  const geometry::PinholeCamera cam = synth::default_camera();
  synth::TrajectorySpec spec;
  spec.frames = frames;
  spec.speed = c.speed;
  spec.T0 = geometry::look_at(c.distance, c.azimuth, c.elevation);
  const auto truth = synth::make_trajectory(spec);
  synth::RenderOptions ro;
  ro.colour = false;
  synth::Renderer renderer(cam, ro);
  pipeline::SingleObjectTracker tracker(model, cam);
  tracker.set_pose(truth[0]);
  SequenceResult r;
  std::vector<geometry::SE3> est;
  for (int i = 0; i < frames; ++i) {
    const cv::Mat img = renderer.render(*model, truth[i], i);
    const auto fr = tracker.track(io::as_view(img));
    est.push_back(fr.T_cam_obj);
    if (fr.report.status == scene::TrackStatus::kLost) ++r.lost;
    r.mean_used += fr.report.features_used;
  }
  r.mean_used /= frames;
  r.acc = pipeline::evaluate(est, truth);
  return r;
}

class RegularSequence : public ::testing::TestWithParam<SequenceCase> {};

TEST_P(RegularSequence, TracksEveryFrameWithinSubMillimetre) {
  const SequenceCase& c = GetParam();
  const SequenceResult r = run_sequence(c);
  RecordProperty("mean_translation_mm", fmt::format("{:.4f}", r.acc.mean_translation_m * 1e3));
  RecordProperty("mean_rotation_deg", fmt::format("{:.4f}", r.acc.mean_rotation_deg));
  std::printf("[%s] mean t %.4f mm (max %.4f), mean r %.4f deg (max %.4f), lost %d, used %.1f\n", c.name,
              r.acc.mean_translation_m * 1e3, r.acc.max_translation_m * 1e3, r.acc.mean_rotation_deg,
              r.acc.max_rotation_deg, r.lost, r.mean_used);
  EXPECT_EQ(r.lost, 0);
  EXPECT_EQ(r.acc.successes, r.acc.frames);
  EXPECT_LT(r.acc.mean_translation_m, 1e-3);
  EXPECT_LT(r.acc.mean_rotation_deg, 0.3);
}

INSTANTIATE_TEST_SUITE_P(
    Objects, RegularSequence,
    ::testing::Values(SequenceCase{"box", &synth::box_cao, 0.55, -0.6, 0.7, 1.0},
                      SequenceCase{"ship", &synth::ship_mockup_cao, 0.7, -0.6, 0.75, 1.0},
                      SequenceCase{"section", &synth::ship_section_cao, 0.6, -0.6, 0.75, 1.0}),
    [](const ::testing::TestParamInfo<SequenceCase>& i) { return std::string(i.param.name); });

TEST(Tracking, ConvergesFromAnOffsetInitialPose) {
  // The initial pose is 8 mm and 2 degrees off: features are searched at their projection in the
  // wide window, and within a few frames the pose settles on the truth.
  auto m = model::parse_cao(synth::ship_mockup_cao(), "ship");
  ASSERT_TRUE(m.has_value());
  auto model = std::make_shared<const model::Model>(std::move(*m));
  const geometry::PinholeCamera cam = synth::default_camera();
  const geometry::SE3 T = geometry::look_at(0.65, -0.6, 0.75);
  synth::RenderOptions ro;
  ro.colour = false;
  synth::Renderer renderer(cam, ro);
  const cv::Mat img = renderer.render(*model, T, 0);
  geometry::Vector6d d;
  d << 0.006, -0.004, 0.003, 0.02, -0.02, 0.015;
  pipeline::SingleObjectTracker tracker(model, cam);
  tracker.set_pose(T * geometry::SE3::exp(d));  // perturbed about the object origin
  pipeline::FrameResult r;
  for (int i = 0; i < 5; ++i) r = tracker.track(io::as_view(img));
  const double et = (r.T_cam_obj.translation() - T.translation()).norm();
  const double er = geometry::rotation_angle_between(r.T_cam_obj, T) * 180.0 / M_PI;
  EXPECT_LT(et, 1e-3);
  EXPECT_LT(er, 0.2);
  EXPECT_EQ(r.report.status, scene::TrackStatus::kTracking);
}

}  // namespace
