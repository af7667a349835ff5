// v4r - robust model-based object tracking. MIT licence.
// BackgroundSearch (issue 10, item 5): the cycle's thread hands frames to the search's worker
// without touching the heap once the sizes are known, and the worker's result is set on the
// scene at the next apply(). The worker is held by its hook while the allocations are counted
// (the counter sees every thread).
#include <condition_variable>
#include <mutex>
#include <stop_token>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "alloc_counter.hpp"
#include "mat_views.hpp"
#include "v4r/detection/symmetry.hpp"
#include "v4r/detection/template_set.hpp"
#include "v4r/geometry/look_at.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/background_search.hpp"
#include "v4r/synth/renderer.hpp"

using namespace v4r;

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

using v4r::test::cview;
using v4r::test::view;

/// Holds the worker in its hook while `holding` (or until a stop request).
struct Gate {
  std::mutex m;
  std::condition_variable_any cv;
  bool holding = true;
  int taken = 0;
  void hook(std::stop_token st) {
    std::unique_lock lock(m);
    ++taken;
    cv.notify_all();
    cv.wait(lock, st, [&] { return !holding; });
  }
};

}  // namespace

TEST(BackgroundSearch, HandsFramesOverWithoutAllocatingAndSetsTheFoundPose) {
  const geometry::PinholeCamera cam = synth::default_camera();
  auto box = std::make_shared<const model::Model>(std::move(*model::parse_cao(synth::box_cao(), "box")));
  detection::DetectorParams dp;  // a narrow view range: quick to build
  dp.views.azimuth_min_deg = 20;
  dp.views.azimuth_max_deg = 60;
  dp.views.elevation_min_deg = 30;
  dp.views.elevation_max_deg = 50;
  dp.views.inplane_min_deg = -5;
  dp.views.inplane_max_deg = 5;
  auto ts = detection::build_templates(*box, cam, dp);
  ASSERT_TRUE(ts) << ts.error().to_string();
  const geometry::SE3 truth = geometry::look_at(0.7, 40 * kDeg, 40 * kDeg, detection::model_extent(*box).centre);
  synth::Renderer r(cam, synth::RenderOptions{});
  const cv::Mat bgr = r.render(*box, truth, 0);
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  const pipeline::CameraImage img{view(grey), cview(bgr)};

  scene::Scene sc;
  sc.add_camera(scene::Camera{"camera", cam, geometry::SE3()});
  ASSERT_TRUE(sc.add_object("box", box));
  sc.start_search(0);
  pipeline::ObjectSearchParams sp;
  auto search = std::make_unique<pipeline::ObjectSearch>(pipeline::CycleParams{}, sp, dp);
  search->add_object(sc, 0, std::make_shared<const detection::TemplateSet>(std::move(*ts)));
  Gate gate;
  pipeline::BackgroundSearch bg(sp, [&gate](std::stop_token st) { gate.hook(st); });
  bg.set_search(std::move(search), 1);

  // Warm-up: the first frames size the three buffers that circulate between the threads. The
  // worker's buffer is sized only when it takes a frame, and the empty one it gives back reaches
  // the cycle's thread two frames later: so the warm-up waits for the worker to take the first
  // frame (however late its thread runs), then hands over three more.
  const std::span<const pipeline::CameraImage> images(&img, 1);
  test::g_allocations = 0;
  test::g_counting = true;
  EXPECT_EQ(bg.apply(sc), 0);
  bg.update(sc, images, 0.0);
  {
    std::unique_lock lock(gate.m);
    ASSERT_TRUE(gate.cv.wait_for(lock, std::chrono::seconds(30), [&] { return gate.taken == 1; }));
  }
  for (int i = 1; i < 4; ++i) {
    EXPECT_EQ(bg.apply(sc), 0);
    bg.update(sc, images, i / 30.0);
  }
  test::g_counting = false;
  EXPECT_GT(test::g_allocations, 0) << "the first frames size the buffers (and show the counter works)";
  test::g_allocations = 0;
  test::g_counting = true;
  for (int i = 4; i < 24; ++i) {
    bg.apply(sc);
    bg.update(sc, images, i / 30.0);
  }
  test::g_counting = false;
  EXPECT_EQ(test::g_allocations, 0) << "the cycle's thread allocated while handing frames over";
  EXPECT_EQ(bg.frames_searched(), 0);
  EXPECT_EQ(sc.objects()[0].status, scene::TrackStatus::kSearching);

  // Released, the worker finds the box (a candidate, then its confirmation on the next frame it
  // takes); apply() sets it on the scene, and from then on nothing is handed over.
  {
    std::scoped_lock lock(gate.m);
    gate.holding = false;
    gate.cv.notify_all();
  }
  int frame = 24;
  while (sc.objects()[0].status == scene::TrackStatus::kSearching && bg.frames_searched() < 10) {
    bg.apply(sc);
    bg.update(sc, images, frame++ / 30.0);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_EQ(sc.objects()[0].status, scene::TrackStatus::kTracking) << bg.frames_searched() << " frames searched";
  EXPECT_EQ(bg.poses_applied(), 1);
  const auto e = detection::symmetric_pose_error(sc.objects()[0].T_ref_obj, truth, detection::model_symmetries(*box));
  EXPECT_LE(e.translation, 0.01);
  EXPECT_LE(e.rotation, 2.0 * kDeg);
  const std::int64_t searched = bg.frames_searched();
  for (int i = 0; i < 5; ++i) {
    bg.apply(sc);
    bg.update(sc, images, frame++ / 30.0);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_LE(bg.frames_searched(), searched + 1) << "frames handed over for an object no longer searched";
}
