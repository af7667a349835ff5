// v4r - robust model-based object tracking. MIT licence.
// `v4r track --tag family:id:size_m:"tx ty tz rx ry rz"` end to end: a rendered box sequence with
// a tag36h11 pasted on its top face is tracked from no pose, tracking from frame 1 within
// 5 mm / 2 degrees, and so is a scene file's object that has the same tag (`tag:`) and no
// init_pose; errors in the --tag text name the field.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "../libs/detection/tests/tag_scenes.hpp"
#include "cli_harness.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/io/pose_io.hpp"

namespace fs = std::filesystem;
using namespace v4r;

namespace {

using v4r_test::CliRun;

constexpr const char* kTag = "tag36h11:0:0.08:\"0 0 0.05 3.14159265 0 0\"";  // on the box's top face

class TagCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("v4r_tag_cli_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static CliRun run(const std::string& args) { return v4r_test::run_cli(V4R_CLI, args, dir_); }
  static std::string seq(const std::string& f) { return (dir_ / "seq" / f).string(); }
  /// Renders the box sequence once and pastes the tag kTag describes on the box's top face in
  /// every frame; the ground truth is in seq/gt.csv.
  static void paint_sequence() {
    if (painted_) return;
    CliRun r = run("render --model box --frames 6 --out " + (dir_ / "seq").string());
    ASSERT_EQ(r.code, 0) << r.err;
    auto cam = io::load_camera(seq("camera.yaml"));
    ASSERT_TRUE(cam) << cam.error().to_string();
    auto gt = io::load_pose_csv(seq("gt.csv"));
    ASSERT_TRUE(gt) << gt.error().to_string();
    auto spec = detection::parse_tag_spec(kTag, "test");
    ASSERT_TRUE(spec);
    const auto bitmap = detection::scenes::tag36h11_bitmap(0);
    for (const io::PoseRow& row : *gt) {
      const std::string f = seq(cv::format("frames/%06d.png", row.frame));
      cv::Mat img = cv::imread(f, cv::IMREAD_UNCHANGED);
      ASSERT_FALSE(img.empty()) << f;
      detection::scenes::paint_tag(img, bitmap, spec->size_m, row.T_cam_obj * spec->T_obj_tag, *cam);
      ASSERT_TRUE(cv::imwrite(f, img));
    }
    painted_ = true;
  }
  static inline fs::path dir_;
  static inline bool painted_ = false;
};

/// The CSV's rows as fields.
std::vector<std::vector<std::string>> read_csv(const std::string& path) {
  std::ifstream f(path);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(f, line)) {
    std::vector<std::string> row;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) row.push_back(cell);
    rows.push_back(row);
  }
  return rows;
}

/// Rows of a pose CSV against the truth: tracking from frame 1 on (found on frame 0, confirmed on
/// frame 1) and every tracked pose within 5 mm / 2 degrees of the truth itself, not of one of the
/// box's symmetric poses (the tag tells them apart).
void expect_tracking_from_frame_1(const std::vector<std::vector<std::string>>& rows, const std::vector<io::PoseRow>& gt,
                                  const std::string& out) {
  ASSERT_EQ(rows.size(), gt.size() + 1);
  std::size_t status_col = 0;
  for (std::size_t c = 0; c < rows[0].size(); ++c)
    if (rows[0][c] == "status") status_col = c;
  int first = -1;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    if (rows[i][status_col] != "tracking") continue;
    if (first < 0) first = static_cast<int>(i) - 1;
    const io::PoseRow& truth = gt[i - 1];
    const Eigen::Vector3d t(std::stod(rows[i][1]), std::stod(rows[i][2]), std::stod(rows[i][3]));
    const Eigen::Quaterniond q(std::stod(rows[i][4]), std::stod(rows[i][5]), std::stod(rows[i][6]), std::stod(rows[i][7]));
    const double et = (t - truth.T_cam_obj.translation()).norm();
    const double er = Eigen::AngleAxisd(q.toRotationMatrix().transpose() * truth.T_cam_obj.rotation()).angle() * 180.0 / 3.14159265358979;
    EXPECT_LT(et, 0.005) << "frame " << i - 1;
    EXPECT_LT(er, 2.0) << "frame " << i - 1;
  }
  EXPECT_EQ(first, 1) << out;  // found on frame 0, confirmed on frame 1
  for (std::size_t i = 2; i < rows.size(); ++i) EXPECT_EQ(rows[i][status_col], "tracking") << "frame " << i - 1;
}

TEST_F(TagCli, TagErrorsNameTheField) {
  const std::string base = "track --model box --camera c.yaml --input frames --output o.csv --tag ";
  const struct {
    const char* tag;
    const char* field;
  } kCases[] = {{"'tag99h1:0:0.08:0 0 0 0 0 0'", "family"},
                {"'tag36h11:seven:0.08:0 0 0 0 0 0'", "id"},
                {"'tag36h11:0:-1:0 0 0 0 0 0'", "size_m"},
                {"'tag36h11:0:0.08:0 0 0.05 x 0 0'", "rx"},
                {"'tag36h11:0:0.08:0 0 0.05 3.1'", "ry"},
                {"'tag36h11:0:0.08'", "pose"}};
  for (const auto& c : kCases) {
    const CliRun r = run(base + c.tag);
    EXPECT_EQ(r.code, 1) << c.tag << ": " << r.err;
    EXPECT_NE(r.err.find(std::string("--tag: field '") + c.field + "'"), std::string::npos) << c.tag << ": " << r.err;
  }
  // With --scene (the scene file describes the objects) and with the search off.
  CliRun r = run(std::string("track --scene s.yaml --output-dir d --tag ") + "'" + kTag + "'");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("--tag cannot be combined with --scene"), std::string::npos) << r.err;
}

TEST_F(TagCli, TracksTheBoxFromItsTagWithoutAPose) {
  ASSERT_NO_FATAL_FAILURE(paint_sequence());
  CliRun r;
  auto gt = io::load_pose_csv(seq("gt.csv"));
  ASSERT_TRUE(gt) << gt.error().to_string();
  const std::string out = (dir_ / "poses.csv").string();
  // The search is off: --tag has nothing to do.
  r = run("track --model box --camera " + seq("camera.yaml") + " --input " + seq("frames") + " --output " + out +
          " --set search.enabled=false --tag '" + kTag + "'");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--tag"), std::string::npos) << r.err;
  r = run("track --model box --camera " + seq("camera.yaml") + " --input " + seq("frames") + " --output " + out +
          " --cache-dir " + (dir_ / "cache").string() + " --tag '" + kTag + "'");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  expect_tracking_from_frame_1(read_csv(out), *gt, r.out);
}

TEST_F(TagCli, SceneObjectWithATagAndNoInitPoseIsTrackingFromFrame1) {
  ASSERT_NO_FATAL_FAILURE(paint_sequence());
  auto gt = io::load_pose_csv(seq("gt.csv"));
  ASSERT_TRUE(gt) << gt.error().to_string();
  const std::string scene = (dir_ / "tag_scene.yaml").string();
  const std::string head = "cameras:\n  - name: cam\n    calibration: " + seq("camera.yaml") + "\n    input: " +
                           seq("frames") + "\nobjects:\n  - name: box\n    model: " + seq("model.cao") + "\n";
  // The search is off: the tag has nothing to do (an error at the tag's line).
  std::ofstream(scene) << head << "    tag: '" << kTag << "'\n";
  CliRun r = run("track --scene " + scene + " --output-dir " + (dir_ / "scene_out").string() +
                 " --set search.enabled=false");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find(scene + ":8: objects[0].tag: "), std::string::npos) << r.err;
  // A tag the file gets wrong: file:line and field.
  std::ofstream(scene) << head << "    tag: 'tag36h11:0:0.08:0 0 0.05 3.14159265 0'\n";
  r = run("track --scene " + scene + " --output-dir " + (dir_ / "scene_out").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find(scene + ":8: objects[0].tag: field 'rz': missing"), std::string::npos) << r.err;
  std::ofstream(scene) << head << "    tag: '" << kTag << "'\n";
  r = run("track --scene " + scene + " --output-dir " + (dir_ / "scene_out").string() + " --cache-dir " +
          (dir_ / "cache").string());
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  // The scene CSV has the columns of poses.csv, pose T_ref_obj (camera 0 is the reference here).
  expect_tracking_from_frame_1(read_csv((dir_ / "scene_out" / "box.csv").string()), *gt, r.out);
}

}  // namespace
