// v4r - robust model-based object tracking. MIT licence.
// The C++17 facade, compiled as C++17 (see CMakeLists.txt): pose parsing, clear errors, and a
// rendered sequence (made by `v4r render`) tracked through it in mono8, bgr8 and rgb8.
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "v4r/embed/object_tracker.hpp"

namespace fs = std::filesystem;
using v4r::embed::CameraIntrinsics;
using v4r::embed::ObjectTracker;
using v4r::embed::PixelFormat;
using v4r::embed::Pose;
using v4r::embed::TrackOutput;

namespace {

constexpr int kFrames = 12;

class EmbedSequence : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("v4r_embed_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    const std::string cmd = std::string(V4R_CLI) + " render --model box --frames " + std::to_string(kFrames) +
                            " --out " + dir_.string() + " >/dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static CameraIntrinsics camera() {
    cv::FileStorage fsr((dir_ / "camera.yaml").string(), cv::FileStorage::READ);
    cv::Mat K, D;
    fsr["camera_matrix"] >> K;
    fsr["distortion_coefficients"] >> D;
    CameraIntrinsics c;
    c.width = static_cast<int>(fsr["image_width"]);
    c.height = static_cast<int>(fsr["image_height"]);
    c.fx = K.at<double>(0, 0);
    c.fy = K.at<double>(1, 1);
    c.cx = K.at<double>(0, 2);
    c.cy = K.at<double>(1, 2);
    for (int i = 0; i < 5; ++i) c.dist[static_cast<std::size_t>(i)] = D.at<double>(i);
    return c;
  }
  /// Ground truth rows: tx ty tz qw qx qy qz.
  static std::vector<std::vector<double>> truth() {
    std::ifstream in(dir_ / "gt.csv");
    std::string line;
    std::getline(in, line);
    std::vector<std::vector<double>> rows;
    while (std::getline(in, line)) {
      std::vector<double> v;
      std::stringstream ss(line);
      for (std::string f; std::getline(ss, f, ',');) v.push_back(std::stod(f));
      rows.emplace_back(v.begin() + 1, v.end());
    }
    return rows;
  }
  static std::string init_pose() {
    std::ifstream in(dir_ / "init_pose.txt");
    for (std::string l; std::getline(in, l);)
      if (!l.empty() && l[0] != '#') return l;
    return {};
  }
  static inline fs::path dir_;
};

/// Runs the sequence through the facade in `format`; returns the largest translation error (m).
double track_sequence(ObjectTracker& t, const std::vector<std::vector<double>>& gt, const fs::path& frames,
                      PixelFormat format) {
  double worst = 0.0;
  for (int i = 0; i < kFrames; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", i);
    cv::Mat img = cv::imread((frames / name).string(), cv::IMREAD_COLOR);
    if (format == PixelFormat::kMono8) cv::cvtColor(img, img, cv::COLOR_BGR2GRAY);
    if (format == PixelFormat::kRgb8) cv::cvtColor(img, img, cv::COLOR_BGR2RGB);
    TrackOutput out;
    std::string error;
    EXPECT_TRUE(t.track(img.data, img.cols, img.rows, static_cast<int>(img.step[0]), format, i / 30.0, out, error))
        << error;
    EXPECT_STREQ(out.status, "tracking") << "frame " << i;
    double e2 = 0.0;
    for (int k = 0; k < 3; ++k) e2 += std::pow(out.pose.t[static_cast<std::size_t>(k)] - gt[static_cast<std::size_t>(i)][static_cast<std::size_t>(k)], 2);
    worst = std::max(worst, std::sqrt(e2));
    for (int k = 0; k < 6; ++k) EXPECT_GT(out.covariance[static_cast<std::size_t>(k * 7)], 0.0) << "diagonal " << k;
    EXPECT_NEAR(out.covariance[1], out.covariance[6], 1e-9 * std::abs(out.covariance[0]));  // symmetric
  }
  return worst;
}

TEST(Embed, ParsePose) {
  Pose p;
  std::string error;
  ASSERT_TRUE(v4r::embed::parse_pose("0.1 0.2 0.6 0 0 0", p, error)) << error;
  EXPECT_DOUBLE_EQ(p.t[2], 0.6);
  EXPECT_DOUBLE_EQ(p.q[0], 1.0);
  ASSERT_TRUE(v4r::embed::parse_pose("0 0 1 0 0 3.141592653589793", p, error));
  EXPECT_NEAR(std::abs(p.q[3]), 1.0, 1e-12);
  EXPECT_FALSE(v4r::embed::parse_pose("0 0 1 0 0", p, error));
  EXPECT_NE(error.find("number 6"), std::string::npos) << error;
  EXPECT_FALSE(v4r::embed::parse_pose("0 0 1 0 0 x", p, error));
  EXPECT_FALSE(v4r::embed::parse_pose("0 0 1 0 0 0 7", p, error));
  EXPECT_NE(error.find("more"), std::string::npos) << error;
}

TEST(Embed, MissingModelIsNamed) {
  std::string error;
  v4r::embed::TrackerOptions o;
  o.model = "/nonexistent/model.cao";
  EXPECT_EQ(ObjectTracker::create(o, error), nullptr);
  EXPECT_NE(error.find("/nonexistent/model.cao"), std::string::npos) << error;
}

TEST_F(EmbedSequence, RefusesFramesBeforeCameraAndPoseAndOfTheWrongSize) {
  std::string error;
  v4r::embed::TrackerOptions o;
  o.model = (dir_ / "model.cao").string();
  auto t = ObjectTracker::create(o, error);
  ASSERT_NE(t, nullptr) << error;
  std::vector<std::uint8_t> img(64 * 48);
  TrackOutput out;
  EXPECT_FALSE(t->track(img.data(), 64, 48, 64, PixelFormat::kMono8, 0.0, out, error));
  EXPECT_NE(error.find("calibration"), std::string::npos) << error;
  ASSERT_TRUE(t->set_camera(camera(), error)) << error;
  EXPECT_FALSE(t->track(img.data(), 64, 48, 64, PixelFormat::kMono8, 0.0, out, error));
  EXPECT_NE(error.find("pose"), std::string::npos) << error;
  Pose p;
  ASSERT_TRUE(v4r::embed::parse_pose(init_pose(), p, error));
  t->set_pose(p);
  EXPECT_FALSE(t->track(img.data(), 64, 48, 64, PixelFormat::kMono8, 0.0, out, error));
  EXPECT_NE(error.find("64x48"), std::string::npos) << error;
  CameraIntrinsics bad;
  EXPECT_FALSE(t->set_camera(bad, error));
  EXPECT_NE(error.find("invalid camera"), std::string::npos) << error;
}

TEST_F(EmbedSequence, TracksTheRenderedSequenceInEveryPixelFormat) {
  const auto gt = truth();
  ASSERT_EQ(gt.size(), static_cast<std::size_t>(kFrames));
  for (PixelFormat f : {PixelFormat::kMono8, PixelFormat::kBgr8, PixelFormat::kRgb8}) {
    std::string error;
    v4r::embed::TrackerOptions o;
    o.model = (dir_ / "model.cao").string();
    auto t = ObjectTracker::create(o, error);
    ASSERT_NE(t, nullptr) << error;
    ASSERT_TRUE(t->set_camera(camera(), error)) << error;
    Pose p;
    ASSERT_TRUE(v4r::embed::parse_pose(init_pose(), p, error)) << error;
    t->set_pose(p);
    EXPECT_LT(track_sequence(*t, gt, dir_ / "frames", f), 0.005) << "format " << static_cast<int>(f);
  }
}

}  // namespace
