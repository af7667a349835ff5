// v4r - robust model-based object tracking. MIT licence.
// `v4r track --tag family:id:size_m:"tx ty tz rx ry rz"` end to end: a rendered box sequence with
// a tag36h11 pasted on its top face is tracked from no pose, tracking from frame 1 within
// 5 mm / 2 degrees; errors in the --tag text name the field.
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
  static inline fs::path dir_;
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

}  // namespace

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
  CliRun r = run("render --model box --frames 6 --out " + (dir_ / "seq").string());
  ASSERT_EQ(r.code, 0) << r.err;
  auto cam = io::load_camera(seq("camera.yaml"));
  ASSERT_TRUE(cam) << cam.error().to_string();
  auto gt = io::load_pose_csv(seq("gt.csv"));
  ASSERT_TRUE(gt) << gt.error().to_string();
  auto spec = detection::parse_tag_spec("tag36h11:0:0.08:0 0 0.05 3.14159265 0 0", "test");
  ASSERT_TRUE(spec);
  const auto bitmap = detection::scenes::tag36h11_bitmap(0);
  for (const io::PoseRow& row : *gt) {
    const std::string f = seq(cv::format("frames/%06d.png", row.frame));
    cv::Mat img = cv::imread(f, cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(img.empty()) << f;
    detection::scenes::paint_tag(img, bitmap, spec->size_m, row.T_cam_obj * spec->T_obj_tag, *cam);
    ASSERT_TRUE(cv::imwrite(f, img));
  }
  const std::string out = (dir_ / "poses.csv").string();
  // The search is off: --tag has nothing to do.
  r = run("track --model box --camera " + seq("camera.yaml") + " --input " + seq("frames") + " --output " + out +
          " --set search.enabled=false --tag '" + kTag + "'");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--tag"), std::string::npos) << r.err;
  r = run("track --model box --camera " + seq("camera.yaml") + " --input " + seq("frames") + " --output " + out +
          " --cache-dir " + (dir_ / "cache").string() + " --tag '" + kTag + "'");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  const auto rows = read_csv(out);
  ASSERT_EQ(rows.size(), gt->size() + 1);
  std::size_t status_col = 0;
  for (std::size_t c = 0; c < rows[0].size(); ++c)
    if (rows[0][c] == "status") status_col = c;
  int first = -1;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    if (rows[i][status_col] != "tracking") continue;
    if (first < 0) first = static_cast<int>(i) - 1;
    const io::PoseRow& truth = (*gt)[i - 1];
    const Eigen::Vector3d t(std::stod(rows[i][1]), std::stod(rows[i][2]), std::stod(rows[i][3]));
    const Eigen::Quaterniond q(std::stod(rows[i][4]), std::stod(rows[i][5]), std::stod(rows[i][6]), std::stod(rows[i][7]));
    const double et = (t - truth.T_cam_obj.translation()).norm();
    const double er = Eigen::AngleAxisd(q.toRotationMatrix().transpose() * truth.T_cam_obj.rotation()).angle() * 180.0 / 3.14159265358979;
    EXPECT_LT(et, 0.005) << "frame " << i - 1;
    EXPECT_LT(er, 2.0) << "frame " << i - 1;
  }
  EXPECT_EQ(first, 1) << r.out;  // found on frame 0, confirmed on frame 1
  for (std::size_t i = 2; i < rows.size(); ++i) EXPECT_EQ(rows[i][status_col], "tracking") << "frame " << i - 1;
}
