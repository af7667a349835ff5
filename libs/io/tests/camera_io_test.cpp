// v4r - robust model-based object tracking. MIT licence.

#include "v4r/io/camera_io.hpp"

#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace v4r::io {
namespace {

using test::TempDir;
using test::write_file;

std::string to_crlf(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '\n') out += '\r';
    out += c;
  }
  return out;
}

const char* const kOpenCvText =
    "%YAML:1.0\n"
    "---\n"
    "image_width: 640\n"
    "image_height: 480\n"
    "camera_matrix: !!opencv-matrix\n"
    "   rows: 3\n"
    "   cols: 3\n"
    "   dt: d\n"
    "   data: [ 600., 0., 319.5, 0., 600., 239.5, 0., 0., 1. ]\n"
    "distortion_coefficients: !!opencv-matrix\n"
    "   rows: 5\n"
    "   cols: 1\n"
    "   dt: d\n"
    "   data: [ -0.1, 0.01, 0., 0., 0. ]\n";

// As ROS camera_calibration / camera_info_manager write it.
const char* const kRosFileText =
    "image_width: 752\n"
    "image_height: 480\n"
    "camera_name: narrow_stereo\n"
    "camera_matrix:\n"
    "  rows: 3\n"
    "  cols: 3\n"
    "  data: [612.5, 0, 371.25, 0, 611.75, 238.5, 0, 0, 1]\n"
    "distortion_model: plumb_bob\n"
    "distortion_coefficients:\n"
    "  rows: 1\n"
    "  cols: 5\n"
    "  data: [0.1, -0.2, 0.001, -0.002, 0.05]\n"
    "rectification_matrix:\n"
    "  rows: 3\n"
    "  cols: 3\n"
    "  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"
    "projection_matrix:\n"
    "  rows: 3\n"
    "  cols: 4\n"
    "  data: [600.1, 0, 370.2, 0, 0, 601.3, 240.4, 0, 0, 0, 1, 0]\n";

// The sensor_msgs/CameraInfo message form (rostopic echo).
const char* const kRosMessageText =
    "header:\n"
    "  seq: 12\n"
    "  stamp: {secs: 1, nsecs: 2}\n"
    "  frame_id: camera_optical\n"
    "height: 720\n"
    "width: 1280\n"
    "distortion_model: \"plumb_bob\"\n"
    "D: [-0.3, 0.12, 0.0005, 0.0007, -0.02]\n"
    "K: [910.0, 0.0, 640.5, 0.0, 905.0, 360.25, 0.0, 0.0, 1.0]\n"
    "R: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]\n"
    "P: [910.0, 0.0, 640.5, 0.0, 0.0, 905.0, 360.25, 0.0, 0.0, 0.0, 1.0, 0.0]\n"
    "binning_x: 0\n"
    "binning_y: 0\n"
    "roi: {x_offset: 0, y_offset: 0, height: 0, width: 0, do_rectify: False}\n";

void expect_opencv_sample(const geometry::PinholeCamera& c) {
  EXPECT_EQ(c.width, 640);
  EXPECT_EQ(c.height, 480);
  EXPECT_EQ(c.fx, 600.0);
  EXPECT_EQ(c.fy, 600.0);
  EXPECT_EQ(c.cx, 319.5);
  EXPECT_EQ(c.cy, 239.5);
  EXPECT_EQ(c.dist[0], -0.1);
  EXPECT_EQ(c.dist[1], 0.01);
  EXPECT_EQ(c.dist[2], 0.0);
  EXPECT_EQ(c.dist[3], 0.0);
  EXPECT_EQ(c.dist[4], 0.0);
}

TEST(CameraIo, ParsesOpenCvFileStorageYaml) {
  const Expected<geometry::PinholeCamera> c = parse_camera(kOpenCvText, "calib.yml");
  ASSERT_TRUE(c) << c.error().to_string();
  expect_opencv_sample(*c);
}

TEST(CameraIo, ParsesOpenCvYamlWithCrlf) {
  const Expected<geometry::PinholeCamera> c = parse_camera(to_crlf(kOpenCvText), "calib.yml");
  ASSERT_TRUE(c) << c.error().to_string();
  expect_opencv_sample(*c);
}

TEST(CameraIo, ReadsWhatCvFileStorageWrites) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("opencv_written.yml");
  {
    cv::FileStorage fs(path, cv::FileStorage::WRITE);
    ASSERT_TRUE(fs.isOpened());
    fs << "calibration_time"
       << "Thu 01 Jan 1970";
    fs << "image_width" << 1024 << "image_height" << 768;
    const cv::Mat K = (cv::Mat_<double>(3, 3) << 801.123456789012, 0, 511.75, 0, 799.5, 383.25, 0, 0, 1);
    const cv::Mat D = (cv::Mat_<double>(1, 5) << -0.2812345678901, 0.0923, 1.5e-4, -2.5e-4, -0.0125);
    fs << "camera_matrix" << K << "distortion_coefficients" << D << "avg_reprojection_error" << 0.21;
  }
  const Expected<geometry::PinholeCamera> c = load_camera(path);
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->width, 1024);
  EXPECT_EQ(c->height, 768);
  EXPECT_DOUBLE_EQ(c->fx, 801.123456789012);
  EXPECT_DOUBLE_EQ(c->fy, 799.5);
  EXPECT_DOUBLE_EQ(c->cx, 511.75);
  EXPECT_DOUBLE_EQ(c->cy, 383.25);
  EXPECT_DOUBLE_EQ(c->dist[0], -0.2812345678901);
  EXPECT_DOUBLE_EQ(c->dist[1], 0.0923);
  EXPECT_DOUBLE_EQ(c->dist[2], 1.5e-4);
  EXPECT_DOUBLE_EQ(c->dist[3], -2.5e-4);
  EXPECT_DOUBLE_EQ(c->dist[4], -0.0125);
}

TEST(CameraIo, ParsesRosCameraInfoFile) {
  const Expected<geometry::PinholeCamera> c = parse_camera(kRosFileText, "left.yaml");
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->width, 752);
  EXPECT_EQ(c->height, 480);
  // K and D (raw image), not P.
  EXPECT_EQ(c->fx, 612.5);
  EXPECT_EQ(c->fy, 611.75);
  EXPECT_EQ(c->cx, 371.25);
  EXPECT_EQ(c->cy, 238.5);
  EXPECT_EQ(c->dist[0], 0.1);
  EXPECT_EQ(c->dist[1], -0.2);
  EXPECT_EQ(c->dist[2], 0.001);
  EXPECT_EQ(c->dist[3], -0.002);
  EXPECT_EQ(c->dist[4], 0.05);
}

TEST(CameraIo, ParsesRosCameraInfoMessage) {
  const Expected<geometry::PinholeCamera> c = parse_camera(to_crlf(kRosMessageText), "camera_info.yaml");
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->width, 1280);
  EXPECT_EQ(c->height, 720);
  EXPECT_EQ(c->fx, 910.0);
  EXPECT_EQ(c->fy, 905.0);
  EXPECT_EQ(c->cx, 640.5);
  EXPECT_EQ(c->cy, 360.25);
  EXPECT_EQ(c->dist[0], -0.3);
  EXPECT_EQ(c->dist[1], 0.12);
  EXPECT_EQ(c->dist[2], 0.0005);
  EXPECT_EQ(c->dist[3], 0.0007);
  EXPECT_EQ(c->dist[4], -0.02);
}

TEST(CameraIo, ParsesRos2LowercaseMessage) {
  const char* text =
      "height: 480\nwidth: 640\ndistortion_model: rational_polynomial\n"
      "d: [0.01, -0.02, 0.0, 0.0, 0.003, 0.0, 0.0, 0.0]\n"
      "k: [500.0, 0.0, 320.0, 0.0, 501.0, 240.0, 0.0, 0.0, 1.0]\n"
      "r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]\n"
      "p: [500.0, 0.0, 320.0, 0.0, 0.0, 501.0, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0]\n";
  const Expected<geometry::PinholeCamera> c = parse_camera(text, "ros2.yaml");
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->fy, 501.0);
  EXPECT_EQ(c->dist[0], 0.01);
  EXPECT_EQ(c->dist[4], 0.003);
}

TEST(CameraIo, DistortionModelNoneWithEmptyCoefficients) {
  const char* text =
      "height: 480\nwidth: 640\ndistortion_model: none\nD: []\n"
      "K: [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0]\n";
  const Expected<geometry::PinholeCamera> c = parse_camera(text, "none.yaml");
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_FALSE(c->has_distortion());
}

std::string opencv_with_distortion(const std::string& rows, const std::string& data) {
  return "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n"
         "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
         "   data: [ 600., 0., 319.5, 0., 600., 239.5, 0., 0., 1. ]\n"
         "distortion_coefficients: !!opencv-matrix\n   rows: " +
         rows + "\n   cols: 1\n   dt: d\n   data: [ " + data + " ]\n";
}

TEST(CameraIo, DistortionCoefficientCounts) {
  // 4 coefficients: k3 = 0.
  Expected<geometry::PinholeCamera> c = parse_camera(opencv_with_distortion("4", "0.1, 0.2, 0.003, 0.004"), "d4");
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->dist[3], 0.004);
  EXPECT_EQ(c->dist[4], 0.0);
  // 8 coefficients with zero rational terms.
  c = parse_camera(opencv_with_distortion("8", "0.1, 0.2, 0.003, 0.004, 0.5, 0, 0, 0"), "d8");
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->dist[4], 0.5);
  // 8 coefficients with a non-zero k5: refused.
  c = parse_camera(opencv_with_distortion("8", "0.1, 0.2, 0.003, 0.004, 0.5, 0, 0.7, 0"), "d8r");
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().field, "distortion_coefficients");
  EXPECT_NE(c.error().message.find("rational model not supported"), std::string::npos) << c.error().message;
  EXPECT_EQ(c.error().line, 11);  // the mapping under distortion_coefficients starts at "rows"
  // 3 coefficients: too few.
  c = parse_camera(opencv_with_distortion("3", "0.1, 0.2, 0.003"), "d3");
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().field, "distortion_coefficients");
  EXPECT_NE(c.error().message.find("got 3"), std::string::npos) << c.error().message;
  // 6 coefficients: no OpenCV model has 6.
  c = parse_camera(opencv_with_distortion("6", "0.1, 0.2, 0.003, 0.004, 0.5, 0"), "d6");
  ASSERT_FALSE(c);
  EXPECT_NE(c.error().message.find("expected 4, 5 or 8"), std::string::npos) << c.error().message;
}

/// One malformed calibration: the error must carry this field, line (and column when non-zero)
/// and message fragment.
struct Malformed {
  const char* name;
  std::string text;
  const char* field;
  int line;
  int column;
  const char* fragment;
};

class CameraIoMalformed : public ::testing::TestWithParam<Malformed> {};

TEST_P(CameraIoMalformed, ReportsWhereAndWhat) {
  const Malformed& m = GetParam();
  for (const bool crlf : {false, true}) {
    const Expected<geometry::PinholeCamera> c = parse_camera(crlf ? to_crlf(m.text) : m.text, "bad.yml");
    ASSERT_FALSE(c) << m.name;
    const Error& e = c.error();
    EXPECT_EQ(e.file, "bad.yml");
    EXPECT_EQ(e.field, m.field) << e.to_string();
    EXPECT_EQ(e.line, m.line) << e.to_string();
    if (m.column != 0) {
      EXPECT_EQ(e.column, m.column) << e.to_string();
    }
    EXPECT_NE(e.message.find(m.fragment), std::string::npos) << e.to_string();
  }
}

const std::string kHead = "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n";
const std::string kGoodK =
    "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
    "   data: [ 600., 0., 319.5, 0., 600., 239.5, 0., 0., 1. ]\n";
const std::string kGoodD =
    "distortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n"
    "   data: [ -0.1, 0.01, 0., 0., 0. ]\n";

std::string with_k(const std::string& data, const std::string& rows = "3", const std::string& cols = "3") {
  return kHead + "camera_matrix: !!opencv-matrix\n   rows: " + rows + "\n   cols: " + cols + "\n   dt: d\n" +
         "   data: [ " + data + " ]\n" + kGoodD;
}

INSTANTIATE_TEST_SUITE_P(
    Table, CameraIoMalformed,
    ::testing::Values(
        Malformed{"missing_camera_matrix", kHead + kGoodD, "camera_matrix", 0, 0, "missing key"},
        Malformed{"missing_height", "%YAML:1.0\n---\nimage_width: 640\n" + kGoodK + kGoodD, "image_height", 0, 0,
                  "missing key 'image_height'"},
        Malformed{"missing_data", kHead + "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n" + kGoodD,
                  "camera_matrix", 6, 4, "missing 'data'"},
        Malformed{"wrong_matrix_size", with_k("600., 0., 319.5, 0., 0., 600., 239.5, 0., 0., 0., 1., 0.", "3", "4"),
                  "camera_matrix", 6, 4, "expected a 3x3 matrix, got 3x4"},
        Malformed{"data_count_mismatch", with_k("600., 0., 319.5, 0., 600., 239.5, 0., 0."), "camera_matrix", 9, 10,
                  "'data' has 8 values"},
        Malformed{"non_numeric_entry", with_k("600., 0., 319.5, 0., abc, 239.5, 0., 0., 1."), "camera_matrix", 9, 33,
                  "data[4] is not a number: 'abc'"},
        Malformed{"nan_entry", with_k("600., 0., .nan, 0., 600., 239.5, 0., 0., 1."), "camera_matrix", 9, 22,
                  "data[2] is not a finite number"},
        Malformed{"plain_nan_entry", with_k("600., 0., 319.5, 0., 600., nan, 0., 0., 1."), "camera_matrix", 9, 39,
                  "not a finite number: 'nan'"},
        Malformed{"inf_entry", with_k("1e999, 0., 319.5, 0., 600., 239.5, 0., 0., 1."), "camera_matrix", 9, 12,
                  "not a finite number"},
        Malformed{"negative_width", "%YAML:1.0\n---\nimage_width: -640\nimage_height: 480\n" + kGoodK + kGoodD,
                  "image_width", 3, 14, "must be positive"},
        Malformed{"fractional_height", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480.5\n" + kGoodK + kGoodD,
                  "image_height", 4, 15, "whole number"},
        Malformed{"text_width", "%YAML:1.0\n---\nimage_width: wide\nimage_height: 480\n" + kGoodK + kGoodD,
                  "image_width", 3, 14, "not a number"},
        Malformed{"zero_fx", with_k("0., 0., 319.5, 0., 600., 239.5, 0., 0., 1."), "camera_matrix", 6, 4,
                  "fx must be positive"},
        Malformed{"negative_fy", with_k("600., 0., 319.5, 0., -600., 239.5, 0., 0., 1."), "camera_matrix", 6, 4,
                  "fy must be positive"},
        Malformed{"bad_last_row", with_k("600., 0., 319.5, 0., 600., 239.5, 0., 0., 2."), "camera_matrix", 6, 4,
                  "last row must be 0 0 1"},
        Malformed{"skew", with_k("600., 1.5, 319.5, 0., 600., 239.5, 0., 0., 1."), "camera_matrix", 6, 4,
                  "skew must be zero"},
        Malformed{"bad_indentation",
                  kHead + "camera_matrix: !!opencv-matrix\n   rows: 3\n  cols: 3\n   dt: d\n" +
                      "   data: [ 600., 0., 319.5, 0., 600., 239.5, 0., 0., 1. ]\n" + kGoodD,
                  "", 7, 3, "end of map not found"},
        Malformed{"unclosed_flow_sequence",
                  kHead + "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n" +
                      "   data: [ 600., 0., 319.5, 0., 600., 239.5, 0., 0., 1.\n" + kGoodD,
                  "", 10, 0, "end of sequence flow not found"},
        Malformed{"unsupported_model",
                  "image_width: 640\nimage_height: 480\ndistortion_model: equidistant\n"
                  "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [600, 0, 320, 0, 600, 240, 0, 0, 1]\n"
                  "distortion_coefficients:\n  rows: 1\n  cols: 4\n  data: [0.1, 0.01, 0.001, 0.0001]\n",
                  "distortion_model", 3, 19, "unsupported distortion model 'equidistant'"},
        Malformed{"rational_with_k6",
                  "height: 480\nwidth: 640\ndistortion_model: rational_polynomial\n"
                  "D: [0.01, -0.02, 0.0, 0.0, 0.003, 0.0, 0.0, 0.25]\n"
                  "K: [500.0, 0.0, 320.0, 0.0, 501.0, 240.0, 0.0, 0.0, 1.0]\n",
                  "D", 4, 4, "rational model not supported"},
        Malformed{"message_K_too_short",
                  "height: 480\nwidth: 640\ndistortion_model: plumb_bob\nD: [0.0, 0.0, 0.0, 0.0, 0.0]\n"
                  "K: [500.0, 0.0, 320.0, 0.0, 501.0, 240.0, 0.0, 0.0]\n",
                  "K", 5, 4, "got 8 values"},
        Malformed{"bad_projection_matrix",
                  std::string(kRosFileText).replace(std::string(kRosFileText).find("cols: 4"), 7, "cols: 3"),
                  "projection_matrix", 20, 9, "'data' has 12 values but rows x cols = 3x3"},
        Malformed{"not_a_mapping", "- 1\n- 2\n", "", 1, 1, "expected a mapping"},
        Malformed{"empty", "", "", 1, 1, "expected a mapping"}),
    [](const ::testing::TestParamInfo<Malformed>& info) { return std::string(info.param.name); });

TEST(CameraIo, MissingFileNamesThePath) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("no_such_calibration.yml");
  const Expected<geometry::PinholeCamera> c = load_camera(path);
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().file, path);
  EXPECT_NE(c.error().message.find("not found"), std::string::npos);
  EXPECT_NE(c.error().message.find(path), std::string::npos);
}

TEST(CameraIo, LoadErrorsNameTheFileAndLine) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("bad.yml");
  write_file(path, to_crlf(with_k("600., 0., 319.5, 0., abc, 239.5, 0., 0., 1.")));
  const Expected<geometry::PinholeCamera> c = load_camera(path);
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().to_string(), path + ":9:33: camera_matrix: data[4] is not a number: 'abc'");
}

geometry::PinholeCamera sample_camera() {
  geometry::PinholeCamera cam;
  cam.width = 1920;
  cam.height = 1080;
  cam.fx = 1402.123456789012345;
  cam.fy = 1399.87654321;
  cam.cx = 959.5 + 1.0 / 3.0;
  cam.cy = 539.5 - 1.0 / 7.0;
  cam.dist = {-0.281234567890123, 0.0923, 1.0e-5, -2.5e-4, -0.0125};
  return cam;
}

TEST(CameraIo, SaveThenLoadIsExact) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("saved.yml");
  const geometry::PinholeCamera cam = sample_camera();
  const Expected<void> saved = save_camera_opencv(path, cam);
  ASSERT_TRUE(saved) << saved.error().to_string();
  const Expected<geometry::PinholeCamera> c = load_camera(path);
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->width, cam.width);
  EXPECT_EQ(c->height, cam.height);
  EXPECT_EQ(c->fx, cam.fx);
  EXPECT_EQ(c->fy, cam.fy);
  EXPECT_EQ(c->cx, cam.cx);
  EXPECT_EQ(c->cy, cam.cy);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(c->dist[i], cam.dist[i]) << i;
}

TEST(CameraIo, SavedFileIsReadByCvFileStorage) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("saved_for_opencv.yml");
  const geometry::PinholeCamera cam = sample_camera();
  ASSERT_TRUE(save_camera_opencv(path, cam));
  cv::FileStorage fs(path, cv::FileStorage::READ);
  ASSERT_TRUE(fs.isOpened());
  int w = 0, h = 0;
  fs["image_width"] >> w;
  fs["image_height"] >> h;
  cv::Mat K, D;
  fs["camera_matrix"] >> K;
  fs["distortion_coefficients"] >> D;
  EXPECT_EQ(w, cam.width);
  EXPECT_EQ(h, cam.height);
  ASSERT_EQ(K.rows, 3);
  ASSERT_EQ(K.cols, 3);
  ASSERT_EQ(K.type(), CV_64F);
  EXPECT_EQ(K.at<double>(0, 0), cam.fx);
  EXPECT_EQ(K.at<double>(0, 1), 0.0);
  EXPECT_EQ(K.at<double>(0, 2), cam.cx);
  EXPECT_EQ(K.at<double>(1, 0), 0.0);
  EXPECT_EQ(K.at<double>(1, 1), cam.fy);
  EXPECT_EQ(K.at<double>(1, 2), cam.cy);
  EXPECT_EQ(K.at<double>(2, 0), 0.0);
  EXPECT_EQ(K.at<double>(2, 1), 0.0);
  EXPECT_EQ(K.at<double>(2, 2), 1.0);
  ASSERT_EQ(D.total(), 5u);
  ASSERT_EQ(D.type(), CV_64F);
  for (int i = 0; i < 5; ++i) EXPECT_EQ(D.at<double>(i), cam.dist[i]) << i;
}

TEST(CameraIo, SaveRefusesInvalidCamera) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  geometry::PinholeCamera cam = sample_camera();
  cam.fx = -1.0;
  EXPECT_FALSE(save_camera_opencv(dir.file("a.yml"), cam));
  cam = sample_camera();
  cam.width = 0;
  EXPECT_FALSE(save_camera_opencv(dir.file("b.yml"), cam));
  cam = sample_camera();
  cam.dist[1] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(save_camera_opencv(dir.file("c.yml"), cam));
  const Expected<void> r = save_camera_opencv(dir.file("no_dir/d.yml"), sample_camera());
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("no_dir/d.yml"), std::string::npos);
}

}  // namespace
}  // namespace v4r::io
