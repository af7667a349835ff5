// v4r - robust model-based object tracking. MIT licence.
// `v4r track --scene` end to end: a stereo pair and two objects in one camera, rendered here with
// ground truth, tracked through the command line; and the scene file's errors as the user sees them.
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "cli_harness.hpp"
#include "v4r/detection/symmetry.hpp"
#include "v4r/geometry/look_at.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/evaluation.hpp"
#include "v4r/synth/renderer.hpp"

namespace fs = std::filesystem;
using namespace v4r;

namespace {

using v4r_test::BadScene;
using v4r_test::CliRun;

/// The stereo rig of the issue: the right camera 12 cm to the right of the left one, toed in 5 degrees.
geometry::SE3 T_left_right() {
  const double toe_in = 5.0 * M_PI / 180.0;
  return geometry::SE3(Eigen::Quaterniond(Eigen::AngleAxisd(-toe_in, Eigen::Vector3d::UnitY())),
                       Eigen::Vector3d(0.12, 0.0, 0.0));
}

std::string pose_list(const geometry::SE3& T) {
  const geometry::Vector6d xi = T.log();
  const Eigen::Vector3d w = xi.tail<3>();
  const Eigen::Vector3d t = T.translation();
  return fmt::format("[{:.9g}, {:.9g}, {:.9g}, {:.9g}, {:.9g}, {:.9g}]", t.x(), t.y(), t.z(), w.x(), w.y(), w.z());
}

std::vector<geometry::SE3> read_poses(const fs::path& csv) {
  std::vector<geometry::SE3> out;
  auto rows = io::load_pose_csv(csv.string());
  if (!rows) return out;
  for (const auto& r : *rows) out.push_back(r.T_cam_obj);
  return out;
}

class SceneTrack : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("v4r_scene_track_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    cam_ = synth::default_camera();
    ASSERT_TRUE(io::save_camera_opencv((dir_ / "camera.yaml").string(), cam_));
    std::ofstream(dir_ / "box.cao") << synth::box_cao();
    std::ofstream(dir_ / "flange.cao") << synth::flange_cao();
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static CliRun run(const std::string& args) { return v4r_test::run_cli(V4R_CLI, args, dir_); }
  static void write(const std::string& name, const std::string& text) { std::ofstream(dir_ / name) << text; }

  static inline fs::path dir_;
  static inline geometry::PinholeCamera cam_;
};

constexpr int kFrames = 40;

TEST_F(SceneTrack, StereoPairTracksInTheReferenceFrameAndIsNoWorseThanOneCamera) {
  auto model = model::parse_cao(synth::box_cao(), "box");
  ASSERT_TRUE(model);
  synth::TrajectorySpec spec;
  spec.frames = kFrames;
  spec.T0 = geometry::look_at(0.55, -0.6, 0.75);
  const std::vector<geometry::SE3> truth = synth::make_trajectory(spec);  // T_left_obj = T_ref_obj
  const geometry::SE3 T_lr = T_left_right();
  synth::RenderOptions ro;
  ro.colour = false;
  ro.cycle_frames = kFrames;
  synth::Renderer left(cam_, ro), right(cam_, ro);
  fs::create_directories(dir_ / "stereo_left");
  fs::create_directories(dir_ / "stereo_right");
  for (int i = 0; i < kFrames; ++i) {
    const geometry::SE3 T_right_obj = T_lr.inverse() * truth[i];
    ASSERT_TRUE(cv::imwrite((dir_ / "stereo_left" / fmt::format("{:06d}.png", i)).string(), left.render(*model, truth[i], i)));
    ASSERT_TRUE(
        cv::imwrite((dir_ / "stereo_right" / fmt::format("{:06d}.png", i)).string(), right.render(*model, T_right_obj, i)));
  }
  // The start pose 2 cm and 3 degrees off the truth, as a user would give it.
  const geometry::SE3 init =
      geometry::SE3::exp((geometry::Vector6d() << 0.01, -0.01, 0.015, 0.03, -0.03, 0.03).finished()) * truth[0];
  const std::string left_cam = "  - name: left\n    calibration: camera.yaml\n    input: stereo_left\n";
  const std::string right_cam = "  - name: right\n    calibration: camera.yaml\n    input: stereo_right\n    T_ref_cam: " +
                                pose_list(T_lr) + "\n";
  const std::string objects = "objects:\n  - name: box\n    model: box.cao\n    init_pose: " + pose_list(init) + "\n";
  write("stereo.yaml", "reference_frame: left\ncameras:\n" + left_cam + right_cam + objects);
  write("mono.yaml", "cameras:\n" + left_cam + objects);

  const CliRun rs = run("track --scene " + (dir_ / "stereo.yaml").string() + " --output-dir " +
                        (dir_ / "out_stereo").string() + " --overlay " + (dir_ / "overlay").string());
  ASSERT_EQ(rs.code, 0) << rs.err;
  const CliRun rm = run("track --scene " + (dir_ / "mono.yaml").string() + " --output-dir " + (dir_ / "out_mono").string());
  ASSERT_EQ(rm.code, 0) << rm.err;

  const auto stereo = read_poses(dir_ / "out_stereo" / "box.csv");
  const auto mono = read_poses(dir_ / "out_mono" / "box.csv");
  ASSERT_EQ(stereo.size(), static_cast<std::size_t>(kFrames));
  ASSERT_EQ(mono.size(), static_cast<std::size_t>(kFrames));
  // Frame 0 is the given start pose: evaluated from frame 1.
  const std::vector<geometry::SE3> t1(truth.begin() + 1, truth.end());
  const auto s = pipeline::evaluate(std::vector<geometry::SE3>(stereo.begin() + 1, stereo.end()), t1);
  const auto m = pipeline::evaluate(std::vector<geometry::SE3>(mono.begin() + 1, mono.end()), t1);
  RecordProperty("stereo_mean_translation_mm", std::to_string(s.mean_translation_m * 1e3));
  RecordProperty("mono_mean_translation_mm", std::to_string(m.mean_translation_m * 1e3));
  std::printf("stereo: mean %.2f mm %.2f deg, success %d/%d; left alone: mean %.2f mm %.2f deg, success %d/%d\n",
              s.mean_translation_m * 1e3, s.mean_rotation_deg, s.successes, s.frames, m.mean_translation_m * 1e3,
              m.mean_rotation_deg, m.successes, m.frames);
  EXPECT_EQ(s.successes, s.frames);
  EXPECT_LT(s.mean_translation_m, 0.005);
  EXPECT_LT(s.mean_rotation_deg, 1.0);
  // The second camera's view enters the pose: at least as accurate as the left camera alone.
  EXPECT_LE(s.mean_translation_m, m.mean_translation_m);
  // One overlay stream per camera.
  EXPECT_TRUE(fs::exists(dir_ / "overlay" / "left" / "000000.png"));
  EXPECT_TRUE(fs::exists(dir_ / "overlay" / "right" / fmt::format("{:06d}.png", kFrames - 1)));
}

TEST_F(SceneTrack, TwoObjectsInOneCameraEachGetTheirOwnCsv) {
  auto box = model::parse_cao(synth::box_cao(), "box");
  auto flange = model::parse_cao(synth::flange_cao(), "flange");
  ASSERT_TRUE(box);
  ASSERT_TRUE(flange);
  // Side by side, each moving on its own trajectory; they never overlap in the image.
  synth::TrajectorySpec sb, sf;
  sb.frames = sf.frames = kFrames;
  sb.translation_amp = sf.translation_amp = 0.02;
  sb.T0 = geometry::look_at(0.6, -0.6, 0.75);
  sb.T0 = geometry::SE3(sb.T0.quaternion(), sb.T0.translation() + Eigen::Vector3d(-0.15, 0.0, 0.0));
  sf.T0 = geometry::look_at(0.6, 0.5, 0.8);
  sf.T0 = geometry::SE3(sf.T0.quaternion(), sf.T0.translation() + Eigen::Vector3d(0.15, 0.0, 0.0));
  const auto tb = synth::make_trajectory(sb), tf = synth::make_trajectory(sf);
  synth::RenderOptions ro;
  ro.colour = false;
  ro.cycle_frames = kFrames;
  synth::Renderer r(cam_, ro);
  fs::create_directories(dir_ / "two");
  for (int i = 0; i < kFrames; ++i) {
    synth::FrameInfo ib, iflange;
    cv::Mat img = r.render(*box, tb[i], i, nullptr, &ib);
    const cv::Mat img_f = r.render(*flange, tf[i], i, nullptr, &iflange);
    ASSERT_EQ(cv::countNonZero(ib.object_mask & iflange.object_mask), 0) << "frame " << i << ": the objects overlap";
    img_f.copyTo(img, iflange.object_mask);
    ASSERT_TRUE(cv::imwrite((dir_ / "two" / fmt::format("{:06d}.png", i)).string(), img));
  }
  write("two.yaml", "cameras:\n  - name: cam\n    calibration: camera.yaml\n    input: two\nobjects:\n"
                    "  - name: box\n    model: box.cao\n    init_pose: " + pose_list(tb[0]) + "\n"
                    "  - name: flange\n    model: flange.cao\n    init_pose: " + pose_list(tf[0]) + "\n");
  const CliRun rr = run("track --scene " + (dir_ / "two.yaml").string() + " --output-dir " + (dir_ / "out_two").string());
  ASSERT_EQ(rr.code, 0) << rr.err;
  for (const auto& [name, truth] : {std::pair{"box", &tb}, std::pair{"flange", &tf}}) {
    SCOPED_TRACE(name);
    const auto est = read_poses(dir_ / "out_two" / (std::string(name) + ".csv"));
    ASSERT_EQ(est.size(), static_cast<std::size_t>(kFrames));
    const auto a = pipeline::evaluate(est, *truth);
    std::printf("%s: mean %.2f mm %.2f deg, success %d/%d\n", name, a.mean_translation_m * 1e3, a.mean_rotation_deg,
                a.successes, a.frames);
    EXPECT_EQ(a.successes, a.frames);
    EXPECT_LT(a.mean_translation_m, 0.005);
    EXPECT_LT(a.mean_rotation_deg, 1.0);
  }
}

/// Rows of a scene CSV as text: the status and, when given, the pose (empty fields while searching).
struct CsvRow {
  std::string status;
  bool has_pose = false;
  geometry::SE3 T;
};

std::vector<CsvRow> read_rows(const fs::path& csv) {
  std::vector<CsvRow> rows;
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::size_t a = 0;
    for (std::size_t b; (b = line.find(',', a)) != std::string::npos; a = b + 1) f.push_back(line.substr(a, b - a));
    f.push_back(line.substr(a));
    if (f.size() < 10) break;
    CsvRow r;
    r.status = f[9];
    r.has_pose = !f[1].empty();
    if (r.has_pose)
      r.T = geometry::SE3(Eigen::Quaterniond(std::stod(f[4]), std::stod(f[5]), std::stod(f[6]), std::stod(f[7])).normalized(),
                          Eigen::Vector3d(std::stod(f[1]), std::stod(f[2]), std::stod(f[3])));
    rows.push_back(r);
  }
  return rows;
}

TEST_F(SceneTrack, AnObjectWithoutInitPoseIsFoundAndThenTrackedOverBothCameras) {
  auto model = model::parse_cao(synth::box_cao(), "box");
  ASSERT_TRUE(model);
  constexpr int kN = 16;
  synth::TrajectorySpec spec;
  spec.frames = kN;
  spec.T0 = geometry::look_at(0.6, -0.5, 0.8);
  const std::vector<geometry::SE3> truth = synth::make_trajectory(spec);
  const geometry::SE3 T_lr = T_left_right();
  synth::RenderOptions ro;
  ro.cycle_frames = kN;
  synth::Renderer left(cam_, ro), right(cam_, ro);
  fs::create_directories(dir_ / "find_left");
  fs::create_directories(dir_ / "find_right");
  for (int i = 0; i < kN; ++i) {
    ASSERT_TRUE(cv::imwrite((dir_ / "find_left" / fmt::format("{:06d}.png", i)).string(), left.render(*model, truth[i], i)));
    ASSERT_TRUE(cv::imwrite((dir_ / "find_right" / fmt::format("{:06d}.png", i)).string(),
                            right.render(*model, T_lr.inverse() * truth[i], i)));
  }
  write("find.yaml", "cameras:\n  - name: left\n    calibration: camera.yaml\n    input: find_left\n"
                     "  - name: right\n    calibration: camera.yaml\n    input: find_right\n    T_ref_cam: " +
                         pose_list(T_lr) + "\nobjects:\n  - name: box\n    model: box.cao\n");
  const CliRun r = run("track --scene " + (dir_ / "find.yaml").string() + " --output-dir " + (dir_ / "out_find").string() +
                       " --cache-dir " + (dir_ / "cache").string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto rows = read_rows(dir_ / "out_find" / "box.csv");
  const auto symmetries = detection::model_symmetries(*model);  // a box is found modulo its symmetries
  ASSERT_EQ(rows.size(), static_cast<std::size_t>(kN));
  int first = -1;
  for (int i = 0; i < kN; ++i) {
    const CsvRow& row = rows[static_cast<std::size_t>(i)];
    if (row.status == "searching") {
      EXPECT_FALSE(row.has_pose) << "frame " << i << ": a searching row has no pose";
      EXPECT_LT(first, 0) << "frame " << i << ": searching again after the object was found";
      continue;
    }
    if (first < 0) first = i;
    ASSERT_TRUE(row.has_pose) << "frame " << i;
    EXPECT_EQ(row.status, "tracking") << "frame " << i;
    const auto e = detection::symmetric_pose_error(row.T, truth[static_cast<std::size_t>(i)], symmetries);
    const double et = e.translation, er = e.rotation * 180.0 / M_PI;
    EXPECT_LT(et, 0.01) << "frame " << i;
    EXPECT_LT(er, 2.0) << "frame " << i;
  }
  std::printf("found without a pose: tracking from frame %d of %d\n", first, kN);
  EXPECT_GE(first, 0);
  EXPECT_LE(first, 10) << "the issue asks for tracking by frame 10";
}

TEST_F(SceneTrack, SceneFileErrorsNameFileLineAndFieldAndFail) {
  fs::create_directories(dir_ / "frames3");
  fs::create_directories(dir_ / "frames5");
  cv::Mat grey(cam_.height, cam_.width, CV_8UC1, cv::Scalar(128));
  for (int i = 0; i < 5; ++i) {
    if (i < 3) cv::imwrite((dir_ / "frames3" / fmt::format("{:06d}.png", i)).string(), grey);
    cv::imwrite((dir_ / "frames5" / fmt::format("{:06d}.png", i)).string(), grey);
  }
  const std::string cam_a = "  - name: a\n    calibration: camera.yaml\n    input: frames5\n";
  const std::string obj = "objects:\n  - name: box\n    model: box.cao\n    init_pose: [0, 0, 0.5, 0, 0, 0]\n";
  const BadScene cases[] = {
      {"unknown key", "cameras:\n" + cam_a + "    T_cam_ref: [0, 0, 0, 0, 0, 0]\n" + obj, 5, "cameras[0].T_cam_ref"},
      {"missing calibration", "cameras:\n  - name: a\n    calibration: nope.yaml\n    input: frames5\n" + obj, 3,
       "cameras[0].calibration"},
      {"missing model", "cameras:\n" + cam_a + "objects:\n  - name: box\n    model: nope.cao\n", 7, "objects[0].model"},
      {"bad pose", "cameras:\n" + cam_a + "objects:\n  - name: box\n    model: box.cao\n    init_pose: [0, 0, 0.5]\n", 8,
       "objects[0].init_pose"},
      {"duplicate name", "cameras:\n" + cam_a + cam_a + obj, 5, "cameras[1].name"},
      {"no cameras", obj, 1, "cameras"},
      {"inputs of unequal length", "cameras:\n" + cam_a + "  - name: b\n    calibration: camera.yaml\n    input: frames3\n" + obj,
       7, "cameras[1].input"},
      {"no objects", "cameras:\n" + cam_a, 1, "objects"},
      {"no objects in the list", "cameras:\n" + cam_a + "objects: []\n", 5, "objects"},
  };
  const std::string path = (dir_ / "bad.yaml").string();
  for (const BadScene& c : cases) {
    SCOPED_TRACE(c.what);
    write("bad.yaml", c.text);
    const CliRun r = run("track --scene " + path + " --output-dir " + (dir_ / "out_bad").string());
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.err.find(fmt::format("{}:{}", path, c.line)), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(std::string(c.field) + ":"), std::string::npos) << r.err;
    // Nothing was tracked: no pose CSV was started.
    EXPECT_FALSE(fs::exists(dir_ / "out_bad" / "box.csv")) << r.err;
  }
}

TEST_F(SceneTrack, SceneAndSingleCameraFlagsDoNotMix) {
  write("ok.yaml", "cameras:\n  - name: a\n    calibration: camera.yaml\n");
  CliRun r = run("track --scene " + (dir_ / "ok.yaml").string() + " --model box --output-dir " + (dir_ / "o").string());
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--model cannot be combined with --scene"), std::string::npos) << r.err;
  r = run("track --scene " + (dir_ / "ok.yaml").string());
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--output-dir"), std::string::npos) << r.err;
}

}  // namespace
