// v4r - robust model-based object tracking. MIT licence.
// `v4r serve --scene`: scene-file errors as the user sees them (file:line and field, non-zero
// exit, before any port is opened). Tracking over the protocol: libs/server/tests/scene_server_test.cpp.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "cli_harness.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/synth/renderer.hpp"

namespace fs = std::filesystem;
using namespace v4r;

namespace {

using v4r_test::BadScene;
using v4r_test::CliRun;

class ServeScene : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("v4r_serve_scene_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "frames3");
    fs::create_directories(dir_ / "frames5");
    const geometry::PinholeCamera cam = synth::default_camera();
    ASSERT_TRUE(io::save_camera_opencv((dir_ / "camera.yaml").string(), cam));
    std::ofstream(dir_ / "box.cao") << synth::box_cao();
    cv::Mat grey(cam.height, cam.width, CV_8UC1, cv::Scalar(128));
    for (int i = 0; i < 5; ++i) {
      if (i < 3) cv::imwrite((dir_ / "frames3" / fmt::format("{:06d}.png", i)).string(), grey);
      cv::imwrite((dir_ / "frames5" / fmt::format("{:06d}.png", i)).string(), grey);
    }
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  // `timeout`: a serve that wrongly starts serving fails the test instead of hanging it.
  static CliRun run(const std::string& args) {
    return v4r_test::run_cli(std::string("timeout 60 ") + V4R_CLI, args, dir_);
  }
  static void write(const std::string& name, const std::string& text) { std::ofstream(dir_ / name) << text; }

  static inline fs::path dir_;
};

TEST_F(ServeScene, SceneFileErrorsNameFileLineAndFieldAndFail) {
  const std::string cam_a = "  - name: a\n    calibration: camera.yaml\n    input: frames5\n";
  const std::string obj = "objects:\n  - name: box\n    model: box.cao\n    init_pose: [0, 0, 0.5, 0, 0, 0]\n";
  const BadScene cases[] = {
      {"unknown key", "cameras:\n" + cam_a + "    T_cam_ref: [0, 0, 0, 0, 0, 0]\n" + obj, 5, "cameras[0].T_cam_ref"},
      {"missing model", "cameras:\n" + cam_a + "objects:\n  - name: box\n    model: nope.cao\n", 7, "objects[0].model"},
      {"bad pose", "cameras:\n" + cam_a + "objects:\n  - name: box\n    model: box.cao\n    init_pose: [0, 0, 0.5]\n", 8,
       "objects[0].init_pose"},
      {"inputs of unequal length", "cameras:\n" + cam_a + "  - name: b\n    calibration: camera.yaml\n    input: frames3\n" + obj,
       7, "cameras[1].input"},
      {"camera without input", "cameras:\n" + cam_a + "  - name: b\n    calibration: camera.yaml\n" + obj, 5, "cameras[1]"},
  };
  const std::string path = (dir_ / "bad.yaml").string();
  for (const BadScene& c : cases) {
    SCOPED_TRACE(c.what);
    write("bad.yaml", c.text);
    const CliRun r = run("serve --port 0 --scene " + path);
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.code, 124) << "serve started instead of refusing the scene file";
    EXPECT_NE(r.err.find(fmt::format("{}:{}", path, c.line)), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(std::string(c.field) + ":"), std::string::npos) << r.err;
    EXPECT_EQ(r.out.find("protocol on"), std::string::npos) << r.out;
  }
}

TEST_F(ServeScene, SceneAndSingleCameraFlagsDoNotMix) {
  write("ok.yaml", "cameras:\n  - name: a\n    calibration: camera.yaml\n    input: frames5\n");
  CliRun r = run("serve --port 0 --scene " + (dir_ / "ok.yaml").string() + " --input frames5");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("give it without --camera and --input"), std::string::npos) << r.err;
  r = run("serve --port 0");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--input is required (or --scene S.yaml)"), std::string::npos) << r.err;
}

}  // namespace
