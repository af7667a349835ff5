// v4r - robust model-based object tracking. MIT licence.
// `v4r serve --scene`: a server over a stereo pair (two inputs read in step), rendered here with
// ground truth. An object added by a client (AddModel, SetPose T_ref_obj) is tracked in every
// camera: ObjectPose gives T_ref_obj and names the reference frame, SystemStatus reports per camera.
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "fixture.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/evaluation.hpp"

namespace v4r::server::test {
namespace {

constexpr int kStereoFrames = 30;

/// The stereo rig of the issue: the right camera 12 cm to the right of the left one, toed in 5 degrees.
geometry::SE3 T_left_right() {
  const double toe_in = 5.0 * M_PI / 180.0;
  return geometry::SE3(Eigen::Quaterniond(Eigen::AngleAxisd(-toe_in, Eigen::Vector3d::UnitY())),
                       Eigen::Vector3d(0.12, 0.0, 0.0));
}

/// A box seen by both cameras, rendered into DIR/left and DIR/right; truth is T_left_obj.
struct Stereo {
  fs::path dir;
  geometry::PinholeCamera camera;
  std::vector<geometry::SE3> truth;
  ~Stereo() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

void render_stereo(Stereo& s) {
  s.dir = fs::temp_directory_path() / ("v4r_scene_server_test_" + std::to_string(::getpid()));
  fs::remove_all(s.dir);
  fs::create_directories(s.dir / "left");
  fs::create_directories(s.dir / "right");
  s.camera = synth::default_camera();
  auto model = model::parse_cao(synth::box_cao(), "box");
  ASSERT_TRUE(model);
  synth::TrajectorySpec spec;
  spec.frames = kStereoFrames;
  spec.T0 = geometry::look_at(0.55, -0.6, 0.75);
  s.truth = synth::make_trajectory(spec);
  synth::RenderOptions ro;
  ro.colour = false;
  ro.cycle_frames = kStereoFrames;
  synth::Renderer left(s.camera, ro), right(s.camera, ro);
  for (int i = 0; i < kStereoFrames; ++i) {
    ASSERT_TRUE(cv::imwrite((s.dir / "left" / fmt::format("{:06d}.png", i)).string(), left.render(*model, s.truth[i], i)));
    ASSERT_TRUE(cv::imwrite((s.dir / "right" / fmt::format("{:06d}.png", i)).string(),
                            right.render(*model, T_left_right().inverse() * s.truth[i], i)));
  }
}

std::unique_ptr<Server> start_scene_server(const Stereo& s) {
  ServerOptions o;
  o.fps = 30.0;
  o.port = 0;
  o.paused = true;
  o.handle_signals = false;
  ServeScene sc;
  sc.cameras = {scene::Camera{"left", s.camera, geometry::SE3()}, scene::Camera{"right", s.camera, T_left_right()}};
  for (const char* name : {"left", "right"}) {
    auto src = io::FrameSource::open((s.dir / name).string());
    if (!src) {
      ADD_FAILURE() << src.error().to_string();
      return nullptr;
    }
    sc.inputs.push_back(std::move(*src));
  }
  sc.reference_frame = "left";
  auto srv = Server::create(std::move(o), std::move(sc));
  if (!srv) {
    ADD_FAILURE() << srv.error().to_string();
    return nullptr;
  }
  (*srv)->start();
  return std::move(*srv);
}

TEST(SceneServer, StereoPairTracksAnObjectAddedByAClientInTheReferenceFrameWithPerCameraStatus) {
  Stereo s;
  ASSERT_NO_FATAL_FAILURE(render_stereo(s));
  auto srv = start_scene_server(s);
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  ASSERT_TRUE(c.is_open());
  ASSERT_NO_FATAL_FAILURE(add_model_inline(c, "box", synth::box_cao()));
  // The start pose 2 cm and 3 degrees off the truth, T_ref_obj (here: the left camera's frame).
  const geometry::SE3 init =
      geometry::SE3::exp((geometry::Vector6d() << 0.01, -0.01, 0.015, 0.03, -0.03, 0.03).finished()) * s.truth[0];
  EXPECT_TRUE(is_ok(ask(c, set_pose("box", init))));
  EXPECT_TRUE(is_ok(ask(c, "Subscribe what=ObjectPose")));
  EXPECT_TRUE(is_ok(ask(c, "Subscribe what=SystemStatus")));
  EXPECT_EQ(ask(c, "Start"), "OK Start frame=0");

  PoseLog log;
  std::map<std::uint64_t, protocol::SystemStatusEvent> status;
  auto done = [&](const PoseLog& l) {
    return has_all(l, "box", kStereoFrames) && status.size() >= static_cast<std::size_t>(kStereoFrames);
  };
  EXPECT_TRUE(collect(c, log, done, 20s, nullptr, &status));
  ASSERT_TRUE(has_all(log, "box", kStereoFrames));

  std::vector<geometry::SE3> est;
  for (const auto& [f, e] : log.at("box")) {
    EXPECT_EQ(e.ref, "left") << "frame " << f;
    EXPECT_GT(e.cov[0], 0.0);
    if (f > 0) est.push_back(to_se3(e));  // frame 0 starts from the given pose
  }
  const auto acc =
      pipeline::evaluate(est, std::vector<geometry::SE3>(s.truth.begin() + 1, s.truth.end()));
  RecordProperty("serve_stereo_mean_translation_mm", std::to_string(acc.mean_translation_m * 1e3));
  std::printf("serve --scene stereo: mean %.2f mm %.2f deg, success %d/%d\n", acc.mean_translation_m * 1e3,
              acc.mean_rotation_deg, acc.successes, acc.frames);
  EXPECT_EQ(acc.successes, acc.frames);
  EXPECT_LT(acc.mean_translation_m, 0.005);
  EXPECT_LT(acc.mean_rotation_deg, 1.0);

  // Per camera: its name, the frames read from its input in step with the other, alive.
  for (const auto& [f, st] : status) {
    ASSERT_EQ(st.cameras.size(), 2u) << "frame " << f;
    EXPECT_EQ(st.cameras[0].name, "left");
    EXPECT_EQ(st.cameras[1].name, "right");
    for (const protocol::CameraStatus& cs : st.cameras) {
      EXPECT_EQ(cs.frames, f + 1) << cs.name << " frame " << f;
      EXPECT_TRUE(cs.alive) << cs.name << " frame " << f;
    }
  }
  EXPECT_GT(status.rbegin()->second.features_used, 0u);
}

TEST(SceneServer, CamerasOfUnequalLengthEndTheInputAndTheServerKeepsAnswering) {
  Stereo s;
  ASSERT_NO_FATAL_FAILURE(render_stereo(s));
  // The right camera loses its last 10 frames: the scene's input ends after the common 20.
  for (int i = kStereoFrames - 10; i < kStereoFrames; ++i) fs::remove(s.dir / "right" / fmt::format("{:06d}.png", i));
  auto srv = start_scene_server(s);
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  ASSERT_TRUE(c.is_open());
  EXPECT_TRUE(is_ok(ask(c, "Subscribe what=SystemStatus")));
  EXPECT_TRUE(is_ok(ask(c, "Start")));
  PoseLog log;
  std::map<std::uint64_t, protocol::SystemStatusEvent> status;
  collect(c, log, [&](const PoseLog&) { return status.size() >= static_cast<std::size_t>(kStereoFrames - 10); }, 10s,
          nullptr, &status);
  ASSERT_EQ(status.size(), static_cast<std::size_t>(kStereoFrames - 10));
  // Nothing after the common end, and the server still answers.
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (!srv->stats().end_of_input && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(10ms);
  EXPECT_TRUE(srv->stats().end_of_input);
  EXPECT_EQ(srv->stats().frames, kStereoFrames - 10);
  EXPECT_TRUE(is_ok(ask(c, "Ping")));
}

}  // namespace
}  // namespace v4r::server::test
