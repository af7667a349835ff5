// v4r - robust model-based object tracking. MIT licence.
// Issue 10, item 5: in `v4r serve` the search of an object runs on a worker thread of its own
// (search.background), so that the other objects' cycles go on while one is searched. A rendered
// scene with a flange tracked from its true pose and a box without a pose (searched); the
// worker is held at will by the service's test seam (search_hook), so that nothing here depends
// on how fast the machine is.
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <stop_token>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "../../detection/tests/tag_scenes.hpp"
#include "fixture.hpp"
#include "v4r/io/loop_source.hpp"
#include "v4r/detection/symmetry.hpp"
#include "v4r/detection/template_cache.hpp"
#include "v4r/detection/template_set.hpp"
#include "v4r/geometry/look_at.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/server/tracking_service.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::server::test {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

using io::LoopSource;

/// T_cam_obj of `m` seen from (azimuth, elevation) at `dist` metres, its centre at pixel (u, v).
geometry::SE3 pose_at(const model::Model& m, const geometry::PinholeCamera& cam, double dist, double az_deg,
                      double el_deg, double u, double v) {
  const Eigen::Vector3d c = detection::model_extent(m).centre;
  const geometry::SE3 T0 = geometry::look_at(dist, az_deg * kDeg, el_deg * kDeg, c);
  const Eigen::Vector3d ray = Eigen::Vector3d((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0).normalized();
  return geometry::SE3(Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), ray), Eigen::Vector3d::Zero()) * T0;
}

/// The scene, its truth and the box's templates (built once per process into a temporary cache,
/// over a narrow view range so that it is quick; the service loads them from there).
struct World {
  geometry::PinholeCamera cam = synth::default_camera();
  std::shared_ptr<const model::Model> box, flange;
  geometry::SE3 T_box, T_flange;  // truth, T_cam_obj
  std::vector<geometry::SE3> box_symmetries;
  std::vector<cv::Mat> frames;
  detection::DetectorParams detect;
  fs::path cache;

  World() {
    box = std::make_shared<const model::Model>(std::move(*model::parse_cao(synth::box_cao(), "box")));
    flange = std::make_shared<const model::Model>(std::move(*model::parse_cao(synth::flange_cao(), "flange")));
    detect.views.azimuth_min_deg = 0;
    detect.views.azimuth_max_deg = 90;
    detect.views.elevation_min_deg = 25;
    detect.views.elevation_max_deg = 60;
    detect.views.inplane_min_deg = -10;
    detect.views.inplane_max_deg = 10;
    T_box = pose_at(*box, cam, 0.75, 40, 40, 190, 250);
    T_flange = pose_at(*flange, cam, 0.75, 20, 45, 470, 230);
    box_symmetries = detection::model_symmetries(*box);
    synth::RenderOptions ro;
    ro.seed = 5;
    synth::Renderer r(cam, ro);
    for (int i = 0; i < 4; ++i) {
      // Each object rendered alone, the nearer laid over the farther.
      synth::FrameInfo info;
      cv::Mat img = r.render(*flange, T_flange, i);
      const cv::Mat b = r.render(*box, T_box, i, nullptr, &info);
      b.copyTo(img, info.object_mask);
      frames.push_back(img);
    }
    cache = fs::temp_directory_path() / ("v4r_background_search_test_" + std::to_string(::getpid()));
    auto t = detection::load_or_build(*box, cam, detect, cache.string());
    EXPECT_TRUE(t) << t.error().to_string();
  }
  ~World() {
    std::error_code ec;
    fs::remove_all(cache, ec);
  }
};

const World& world() {
  static const World w;
  return w;
}

/// A latch on the worker: hold() makes the worker wait in its hook (until release() or a stop
/// request); entered() counts the frames it took.
struct Latch {
  std::mutex m;
  std::condition_variable_any cv;
  bool holding = false;
  int hold_at = -1;  // the worker's frame (1, 2, ...) at which hold turns on by itself
  int entered = 0;
  bool waiting = false;  // the worker waits in the hook now

  void hook(std::stop_token st) {
    std::unique_lock lock(m);
    ++entered;
    if (entered == hold_at) holding = true;
    waiting = holding;
    cv.notify_all();
    cv.wait(lock, st, [&] { return !holding; });
    waiting = false;
  }
  void release() {
    std::scoped_lock lock(m);
    holding = false;
    cv.notify_all();
  }
  /// Waits (up to `timeout`) until the worker waits in the hook.
  bool wait_held(std::chrono::seconds timeout) {
    std::unique_lock lock(m);
    return cv.wait_for(lock, timeout, [&] { return waiting; });
  }
};

/// What the frame callback saw, per frame: the box's and the flange's events.
struct Seen {
  std::mutex m;
  std::condition_variable cv;
  std::vector<protocol::ObjectPoseEvent> box, flange;

  void add(const FrameEvents& ev) {
    std::scoped_lock lock(m);
    for (const protocol::ObjectPoseEvent& p : ev.poses) (p.object == "box" ? box : flange).push_back(p);
    cv.notify_all();
  }
  /// Waits (up to `timeout`) until `pred()` holds (called under the lock).
  template <class Pred>
  bool wait(std::chrono::seconds timeout, Pred pred) {
    std::unique_lock lock(m);
    return cv.wait_for(lock, timeout, pred);
  }
  /// Waits (up to `timeout`) until the box is `tracking` and 5 of its rows are in from then on;
  /// `found` gets the row where it turned `tracking`.
  bool wait_box_tracking(std::chrono::seconds timeout, std::size_t& found) {
    return wait(timeout, [&] {
      for (std::size_t i = 0; i < box.size(); ++i)
        if (box[i].status == protocol::TrackStatus::kTracking) {
          found = i;
          return box.size() >= i + 5;
        }
      return false;
    });
  }
};

/// The service on the world's frames (or `frames`); `box_tag`: the box's StartObject has this tag
/// (the scene file's `tag:`).
std::unique_ptr<TrackingService> make_service(Latch& latch, Seen& seen, bool background = true,
                                              const std::optional<detection::TagSpec>& box_tag = {},
                                              const std::vector<cv::Mat>* frames = nullptr) {
  const World& w = world();
  ServiceOptions o;
  o.camera = w.cam;
  o.fps = 30.0;
  o.detect = w.detect;
  o.cache_dir = w.cache.string();
  o.search.background = background;
  o.objects.push_back(StartObject{"flange", w.flange, w.T_flange, true, {}});
  o.objects.push_back(StartObject{"box", w.box, geometry::SE3(), false, box_tag});  // no pose: searched
  o.search_hook = [&latch](std::stop_token st) { latch.hook(st); };
  auto s = std::make_unique<TrackingService>(std::move(o), std::make_unique<LoopSource>(frames ? *frames : w.frames));
  s->set_frame_callback([&seen](std::shared_ptr<const FrameEvents> ev) { seen.add(*ev); });
  EXPECT_TRUE(s->open());
  return s;
}

void expect_near(const geometry::SE3& T, const geometry::SE3& truth, const std::vector<geometry::SE3>& sym,
                 const std::string& what) {
  const detection::PoseError e = detection::symmetric_pose_error(T, truth, sym);
  EXPECT_LE(e.translation, 0.01) << what;
  EXPECT_LE(e.rotation, 2.0 * kDeg) << what;
}

TEST(BackgroundSearch, OtherObjectsKeepTrackingWhileOneIsSearchedAndItIsFoundWhenTheWorkerGoesOn) {
  const World& w = world();
  Latch latch;
  latch.hold_at = 1;  // the worker waits with its first frame
  Seen seen;
  auto service = make_service(latch, seen);
  service->start();
  ASSERT_TRUE(latch.wait_held(60s)) << "the worker never took a frame (templates not loaded?)";
  // While the worker holds the search, frames go on: the flange tracks, the box is searching.
  std::size_t from = 0;
  {
    std::scoped_lock lock(seen.m);
    from = seen.flange.size();
  }
  ASSERT_TRUE(seen.wait(60s, [&] { return seen.flange.size() >= from + 15; })) << "frames stopped while searching";
  {
    std::scoped_lock lock(seen.m);
    for (std::size_t i = from; i < seen.flange.size(); ++i) {
      const protocol::ObjectPoseEvent& f = seen.flange[i];
      EXPECT_EQ(f.status, protocol::TrackStatus::kTracking) << "frame " << f.frame;
      expect_near(to_se3(f), w.T_flange, {geometry::SE3()}, "flange, frame " + std::to_string(f.frame));
    }
    for (std::size_t i = 0; i < seen.box.size(); ++i)
      EXPECT_EQ(seen.box[i].status, protocol::TrackStatus::kSearching) << "frame " << seen.box[i].frame;
  }
  EXPECT_EQ(service->search()->background()->frames_searched(), 0);
  // Released, the worker finds the box (a candidate, confirmed on its next frame).
  latch.release();
  std::size_t found = 0;
  ASSERT_TRUE(seen.wait_box_tracking(120s, found)) << "the box was not found";
  {
    std::scoped_lock lock(seen.m);
    std::printf("[background search] box tracking at frame %llu after %lld worker frames\n",
                static_cast<unsigned long long>(seen.box[found].frame),
                static_cast<long long>(service->search()->background()->frames_searched()));
    for (std::size_t i = found; i < found + 5; ++i) {
      EXPECT_EQ(seen.box[i].status, protocol::TrackStatus::kTracking) << "frame " << seen.box[i].frame;
      expect_near(to_se3(seen.box[i]), w.T_box, w.box_symmetries, "box, frame " + std::to_string(seen.box[i].frame));
    }
    for (const protocol::ObjectPoseEvent& f : seen.flange) EXPECT_EQ(f.status, protocol::TrackStatus::kTracking);
  }
  EXPECT_EQ(service->search()->background()->poses_applied(), 1);
}

TEST(BackgroundSearch, ASetPoseWhileTheWorkerSearchesWinsOverItsLateResult) {
  const World& w = world();
  Latch latch;
  latch.hold_at = 2;  // the frame on which the worker confirms its first frame's candidate
  Seen seen;
  auto service = make_service(latch, seen);
  service->start();
  ASSERT_TRUE(latch.wait_held(120s)) << "the worker never took a second frame";
  // The client's pose, applied while the worker holds the search that would confirm the box.
  std::mutex m;
  std::condition_variable cv;
  std::string reply;
  const Eigen::Vector3d t = w.T_box.translation(), r = w.T_box.rvec();
  service->submit(protocol::Command{protocol::SetPose{"box", {t.x(), t.y(), t.z()}, {r.x(), r.y(), r.z()}}},
                  [&](std::string s) {
                    std::scoped_lock lock(m);
                    reply = std::move(s);
                    cv.notify_all();
                  });
  {
    std::unique_lock lock(m);
    ASSERT_TRUE(cv.wait_for(lock, 30s, [&] { return !reply.empty(); }));
  }
  ASSERT_TRUE(reply.starts_with("OK SetPose")) << reply;
  const std::uint64_t set_at = std::stoull(reply.substr(reply.find("frame=") + 6));
  latch.release();
  // The worker's result (the confirmed box) arrives after the SetPose: it is dropped.
  const pipeline::BackgroundSearch* bg = service->search()->background();
  ASSERT_TRUE(seen.wait(120s, [&] { return bg->results_dropped() >= 1 && seen.box.size() > set_at + 3; }))
      << "the worker's late result never came (frames searched: " << bg->frames_searched() << ")";
  EXPECT_EQ(bg->poses_applied(), 0);
  std::scoped_lock lock(seen.m);
  for (const protocol::ObjectPoseEvent& b : seen.box) {
    if (b.frame < set_at) {
      EXPECT_EQ(b.status, protocol::TrackStatus::kSearching) << "frame " << b.frame;
    } else {
      EXPECT_EQ(b.status, protocol::TrackStatus::kTracking) << "frame " << b.frame;
      expect_near(to_se3(b), w.T_box, w.box_symmetries, "box, frame " + std::to_string(b.frame));
    }
  }
}

/// Submits a command and waits for its reply.
std::string ask_service(TrackingService& service, protocol::Command c) {
  std::mutex m;
  std::condition_variable cv;
  std::string reply;
  service.submit(std::move(c), [&](std::string s) {
    std::scoped_lock lock(m);
    reply = std::move(s);
    cv.notify_all();
  });
  std::unique_lock lock(m);
  cv.wait_for(lock, 30s, [&] { return !reply.empty(); });
  return reply;
}

TEST(BackgroundSearch, RemovingAnObjectWhileTheWorkerSearchesDropsItsResultAndTheSearchGoesOn) {
  const World& w = world();
  Latch latch;
  latch.hold_at = 2;  // the frame on which the worker would confirm the box
  Seen seen;
  auto service = make_service(latch, seen);
  service->start();
  ASSERT_TRUE(latch.wait_held(120s));
  // The flange (scene index 0) leaves: the box moves to index 0 while the worker holds its search.
  const std::string reply = ask_service(*service, protocol::RemoveObject{"flange"});
  ASSERT_TRUE(reply.starts_with("OK RemoveObject")) << reply;
  latch.release();
  const pipeline::BackgroundSearch* bg = service->search()->background();
  // The worker's result for the scene before is dropped; a new search finds the box again.
  ASSERT_TRUE(seen.wait(120s, [&] { return !seen.box.empty() && seen.box.back().status == protocol::TrackStatus::kTracking; }))
      << "the box was not found after the removal";
  EXPECT_GE(bg->results_dropped(), 1);
  EXPECT_EQ(bg->poses_applied(), 1);
  {
    std::scoped_lock lock(seen.m);
    expect_near(to_se3(seen.box.back()), w.T_box, w.box_symmetries, "box");
  }
  EXPECT_TRUE(service->healthy());
}

TEST(BackgroundSearch, DestroyingTheServiceWhileTheWorkerSearchesReturnsCleanly) {
  // (1) The worker held in its hook: the stop request wakes it, the destructor joins.
  {
    Latch latch;
    latch.hold_at = 1;
    Seen seen;
    auto service = make_service(latch, seen);
    service->start();
    ASSERT_TRUE(latch.wait_held(60s));
    const auto t0 = std::chrono::steady_clock::now();
    service.reset();
    std::printf("[background search] destroyed with the worker held: %.1f ms\n",
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  // (2) The worker in the middle of a search: it stops at its next hypothesis.
  {
    Latch latch;  // never holds: counts the frames the worker took
    Seen seen;
    auto service = make_service(latch, seen);
    service->start();
    {
      std::unique_lock lock(latch.m);
      ASSERT_TRUE(latch.cv.wait_for(lock, 60s, [&] { return latch.entered >= 1; }));
    }
    const auto t0 = std::chrono::steady_clock::now();
    service.reset();
    std::printf("[background search] destroyed while the worker searched: %.1f ms\n",
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
}

TEST(BackgroundSearch, WithoutBackgroundTheSearchRunsOnTheCycleThreadAsBefore) {
  const World& w = world();
  Latch latch;  // the hook is never called: no worker
  Seen seen;
  auto service = make_service(latch, seen, false);
  EXPECT_EQ(service->search()->background(), nullptr);
  service->start();
  ASSERT_TRUE(seen.wait(120s, [&] {
    return !seen.box.empty() && seen.box.back().status == protocol::TrackStatus::kTracking;
  })) << "the box was not found";
  std::scoped_lock lock(seen.m);
  expect_near(to_se3(seen.box.back()), w.T_box, w.box_symmetries, "box");
  EXPECT_EQ(latch.entered, 0);
}

TEST(BackgroundSearch, AStartObjectsTagGivesTheTruePoseWhereTheTemplatesGiveASymmetricOne) {
  // `v4r serve --scene` with an object's `tag:`. The box is seen from azimuth 220 degrees, outside
  // the templates' 0-90: the detector alone finds its symmetric twin (turned 180 degrees about z,
  // azimuth 40). With its tag on the top face the search takes the tag's pose: the true one.
  const World& w = world();
  auto tag = detection::parse_tag_spec("tag36h11:0:0.08:0 0 0.05 3.14159265 0 0", "test");
  ASSERT_TRUE(tag) << tag.error().to_string();
  const geometry::SE3 T_box = pose_at(*w.box, w.cam, 0.75, 220, 40, 190, 250);
  synth::RenderOptions ro;
  ro.seed = 7;
  synth::Renderer r(w.cam, ro);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 4; ++i) {
    synth::FrameInfo info;
    cv::Mat img = r.render(*w.flange, w.T_flange, i);
    const cv::Mat b = r.render(*w.box, T_box, i, nullptr, &info);
    b.copyTo(img, info.object_mask);
    detection::scenes::paint_tag(img, detection::scenes::tag36h11_bitmap(0), tag->size_m, T_box * tag->T_obj_tag, w.cam);
    frames.push_back(img);
  }
  for (const bool with_tag : {true, false}) {
    SCOPED_TRACE(with_tag ? "with the tag" : "without the tag");
    Latch latch;  // never holds
    Seen seen;
    auto service = make_service(latch, seen, true, with_tag ? std::optional(*tag) : std::nullopt, &frames);
    service->start();
    std::size_t found = 0;
    ASSERT_TRUE(seen.wait_box_tracking(120s, found)) << "the box was not found";
    std::scoped_lock lock(seen.m);
    for (std::size_t i = found; i < found + 5; ++i) {
      const std::string what = "box, frame " + std::to_string(seen.box[i].frame);
      EXPECT_EQ(seen.box[i].status, protocol::TrackStatus::kTracking) << what;
      expect_near(to_se3(seen.box[i]), T_box, w.box_symmetries, what);  // right modulo symmetry either way
      const detection::PoseError e = detection::symmetric_pose_error(to_se3(seen.box[i]), T_box, {geometry::SE3()});
      if (with_tag) {
        EXPECT_LE(e.rotation, 2.0 * kDeg) << what << ": the tag tells the symmetric poses apart";
      } else {
        // The check that the scene tests the tag: without it, the symmetric twin.
        EXPECT_GT(e.rotation, 90.0 * kDeg) << what << ": the true pose without the tag: this scene does not test it";
      }
    }
  }
}

}  // namespace
}  // namespace v4r::server::test
