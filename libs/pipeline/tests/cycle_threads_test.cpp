// v4r - robust model-based object tracking. MIT licence.
// The vision cycle on several threads (CycleParams::threads): objects, or one object's camera
// views, measured in parallel give exactly the poses and states of one thread, and allocate
// nothing per frame.
#include <algorithm>
#include <numeric>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "alloc_counter.hpp"
#include "v4r/geometry/look_at.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/vision_cycle.hpp"
#include "v4r/synth/renderer.hpp"

using namespace v4r;

namespace {

/// Two cameras (the second 12 cm to the right, toed in 5 deg) and up to two objects (a box on the
/// left, a flange on the right), rendered in both cameras, nearer objects over farther ones.
struct Rig {
  std::vector<std::shared_ptr<const model::Model>> models;
  std::vector<std::vector<geometry::SE3>> truth;  // per object, per frame: T_ref_obj
  std::vector<geometry::SE3> T_ref_cam;
  std::vector<std::vector<cv::Mat>> grey, bgr;     // per camera, per frame
};

Rig make_rig(int objects, int frames) {
  Rig r;
  r.T_ref_cam = {geometry::SE3(),
                 geometry::SE3(Eigen::Quaterniond(Eigen::AngleAxisd(-5.0 * M_PI / 180.0, Eigen::Vector3d::UnitY())),
                               Eigen::Vector3d(0.12, 0.0, 0.0))};
  const std::string caos[] = {synth::box_cao(), synth::flange_cao()};
  const Eigen::Vector3d offsets[] = {{-0.11, 0.0, 0.0}, {0.11, 0.02, 0.05}};
  synth::TrajectorySpec spec;
  spec.frames = frames;
  spec.T0 = geometry::look_at(0.7, -0.6, 0.75);
  spec.translation_amp = 0.03;
  const std::vector<geometry::SE3> centre = synth::make_trajectory(spec);
  for (int o = 0; o < objects; ++o) {
    r.models.push_back(std::make_shared<const model::Model>(std::move(*model::parse_cao(caos[o], "m"))));
    r.truth.emplace_back();
    for (const geometry::SE3& T : centre) r.truth.back().emplace_back(T.quaternion(), T.translation() + offsets[o]);
  }
  synth::Renderer renderer(synth::default_camera(), synth::RenderOptions{});
  for (const geometry::SE3& T_ref_cam : r.T_ref_cam) {
    r.grey.emplace_back();
    r.bgr.emplace_back();
    for (int i = 0; i < frames; ++i) {
      std::vector<int> order(static_cast<std::size_t>(objects));
      std::iota(order.begin(), order.end(), 0);
      const auto depth = [&](int o) { return (T_ref_cam.inverse() * r.truth[o][i]).translation().z(); };
      std::sort(order.begin(), order.end(), [&](int a, int b) { return depth(a) > depth(b); });
      cv::Mat img;
      for (const int o : order) {
        synth::FrameInfo info;
        const cv::Mat one = renderer.render(*r.models[o], T_ref_cam.inverse() * r.truth[o][i], i, nullptr, &info);
        if (img.empty()) img = one;
        else one.copyTo(img, info.object_mask);
      }
      cv::Mat g;
      cv::cvtColor(img, g, cv::COLOR_BGR2GRAY);
      r.bgr.back().push_back(img);
      r.grey.back().push_back(g);
    }
  }
  return r;
}

scene::Scene make_scene(const Rig& r, int cameras) {
  scene::Scene sc;
  for (int c = 0; c < cameras; ++c)
    sc.add_camera(scene::Camera{"cam" + std::to_string(c), synth::default_camera(), r.T_ref_cam[c]});
  for (std::size_t o = 0; o < r.models.size(); ++o) {
    EXPECT_TRUE(sc.add_object("object" + std::to_string(o), r.models[o]));
    // Started 5 mm off the truth.
    const geometry::SE3& T = r.truth[o][0];
    sc.set_pose(o, geometry::SE3(T.quaternion(), T.translation() + Eigen::Vector3d(0.005, -0.003, 0.004)));
  }
  return sc;
}

std::vector<pipeline::CameraImage> images(const Rig& r, int cameras, int frame) {
  std::vector<pipeline::CameraImage> im;
  for (int c = 0; c < cameras; ++c) {
    const cv::Mat& g = r.grey[c][frame];
    const cv::Mat& b = r.bgr[c][frame];
    im.push_back({{g.ptr<std::uint8_t>(0), g.cols, g.rows, static_cast<int>(g.step[0])},
                  {b.ptr<std::uint8_t>(0), b.cols, b.rows, static_cast<int>(b.step[0])}});
  }
  return im;
}

/// Runs the rig's sequence with `threads` and returns every object's pose per frame; checks the
/// accuracy and counts the heap allocations after the first frame.
struct RunResult {
  std::vector<geometry::SE3> poses;  // frame-major, then object
  std::vector<scene::TrackStatus> status;
  long allocations = 0;
  std::vector<int> alloc_frames;  // frames that allocated
};

RunResult run(const Rig& r, int cameras, int threads, const pipeline::CycleParams& base = {}) {
  scene::Scene sc = make_scene(r, cameras);
  pipeline::CycleParams p = base;
  p.threads = threads;
  pipeline::VisionCycle cycle(p);
  RunResult out;
  const int frames = static_cast<int>(r.grey[0].size());
  std::vector<std::vector<pipeline::CameraImage>> all;
  for (int i = 0; i < frames; ++i) all.push_back(images(r, cameras, i));
  for (int i = 0; i < frames; ++i) {
    test::g_allocations = 0;
    test::g_counting = i > 0;
    cycle.process(sc, all[static_cast<std::size_t>(i)], i / 30.0);
    test::g_counting = false;
    out.allocations += test::g_allocations;
    if (test::g_allocations > 0) out.alloc_frames.push_back(i);
    for (std::size_t o = 0; o < sc.objects().size(); ++o) {
      const scene::Object& obj = sc.objects()[o];
      out.poses.push_back(obj.T_ref_obj);
      out.status.push_back(obj.status);
      EXPECT_TRUE(scene::is_tracked(obj.status)) << "frame " << i << " object " << o;
      EXPECT_LT((obj.T_ref_obj.translation() - r.truth[o][i].translation()).norm(), 0.01)
          << "frame " << i << " object " << o << " threads " << threads;
    }
  }
  return out;
}

void expect_same(const RunResult& a, const RunResult& b) {
  ASSERT_EQ(a.poses.size(), b.poses.size());
  for (std::size_t k = 0; k < a.poses.size(); ++k) {
    EXPECT_EQ(a.status[k], b.status[k]) << "entry " << k;
    EXPECT_EQ((a.poses[k].translation() - b.poses[k].translation()).norm(), 0.0) << "entry " << k;
    EXPECT_EQ(a.poses[k].quaternion().angularDistance(b.poses[k].quaternion()), 0.0) << "entry " << k;
  }
}

}  // namespace

TEST(VisionCycleThreads, TwoObjectsInTwoCamerasOnTwoAndThreeThreadsGiveTheResultsOfOne) {
  const Rig r = make_rig(2, 12);
  const RunResult one = run(r, 2, 1);
  const RunResult two = run(r, 2, 2);
  const RunResult three = run(r, 2, 3);
  expect_same(one, two);
  expect_same(one, three);
  EXPECT_EQ(two.allocations, 0) << "frames " << testing::PrintToString(two.alloc_frames);
  EXPECT_EQ(three.allocations, 0) << "frames " << testing::PrintToString(three.alloc_frames);
}

TEST(VisionCycleThreads, OneObjectsViewsInParallelGiveTheResultsOfOne) {
  // One object: its two camera views are tracked in parallel, solved together.
  const Rig r = make_rig(1, 12);
  const RunResult one = run(r, 2, 1);
  const RunResult two = run(r, 2, 2);
  expect_same(one, two);
  EXPECT_EQ(two.allocations, 0) << "frames " << testing::PrintToString(two.alloc_frames);
}

TEST(VisionCycleThreads, TheTwoViewPerSamplePoseTracksTheRigAndAllocatesNothing) {
  // The per-sample measurement over both views, run every frame and always kept (reaching 10 px:
  // the rig starts 5 mm off): the object's pose is the one both cameras' samples agree on. From
  // one camera alone the same samples let the depth drift (12 mm from frame 9); two views hold it.
  const Rig r = make_rig(1, 12);
  pipeline::CycleParams p;
  p.samples.always = true;
  p.samples.same_px = 0.0;
  p.samples.margin = -1.0;
  p.samples.range_px = 10.0;
  const RunResult kept = run(r, 2, 1, p);
  ASSERT_EQ(kept.poses.size(), r.truth[0].size());
  for (std::size_t i = 0; i < kept.poses.size(); ++i) {
    // Ten iterations a frame take the start's depth error (4 mm) out over the first frames.
    const double mm = 1e3 * (kept.poses[i].translation() - r.truth[0][i].translation()).norm();
    EXPECT_LT(mm, i < 4 ? 5.0 : 1.0) << "frame " << i;
  }
  EXPECT_EQ(kept.allocations, 0) << "frames " << testing::PrintToString(kept.alloc_frames);
  // It moved the pose: not the line solve's.
  const RunResult lines = run(r, 2, 1);
  double moved_mm = 0.0;
  for (std::size_t i = 0; i < kept.poses.size(); ++i)
    moved_mm = std::max(moved_mm, 1e3 * (kept.poses[i].translation() - lines.poses[i].translation()).norm());
  EXPECT_GT(moved_mm, 0.1);
}
