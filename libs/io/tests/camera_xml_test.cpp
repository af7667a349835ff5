// v4r - robust model-based object tracking. MIT licence.
// Calibration files users have: OpenCV FileStorage XML, ViSP's XML camera parameters, files
// without distortion and without the image size.

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

#include "v4r/io/camera_io.hpp"

namespace v4r::io {
namespace {

namespace fs = std::filesystem;

const char* const kVispBoth = R"(<?xml version="1.0"?>
<root>
  <!--This file stores intrinsic camera parameters-->
  <camera>
    <name>Camera</name>
    <image_width>640</image_width>
    <image_height>480</image_height>
    <model>
      <type>perspectiveProjWithoutDistortion</type>
      <px>601.5</px>
      <py>602.5</py>
      <u0>320.5</u0>
      <v0>240.5</v0>
    </model>
    <model>
      <type>perspectiveProjWithDistortion</type>
      <px>600.25</px>
      <py>600.75</py>
      <u0>319.25</u0>
      <v0>239.75</v0>
      <kud>-0.125</kud>
      <kdu>0.13</kdu>
    </model>
  </camera>
</root>
)";

TEST(CameraXml, VispWithDistortionUsesKudAsK1) {
  auto c = parse_camera(kVispBoth, "visp.xml");
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->width, 640);
  EXPECT_EQ(c->height, 480);
  EXPECT_DOUBLE_EQ(c->fx, 600.25);
  EXPECT_DOUBLE_EQ(c->fy, 600.75);
  EXPECT_DOUBLE_EQ(c->cx, 319.25);
  EXPECT_DOUBLE_EQ(c->cy, 239.75);
  EXPECT_DOUBLE_EQ(c->dist[0], -0.125);
  for (int i = 1; i < 5; ++i) EXPECT_EQ(c->dist[i], 0.0);
}

TEST(CameraXml, VispWithoutDistortion) {
  const std::string text = R"(<?xml version="1.0"?>
<root><camera><name>Camera</name><image_width>320</image_width><image_height>240</image_height>
<model><type>perspectiveProjWithoutDistortion</type><px>300</px><py>310</py><u0>160</u0><v0>120</v0></model>
</camera></root>)";
  auto c = parse_camera(text, "visp.xml");
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->width, 320);
  EXPECT_DOUBLE_EQ(c->fx, 300.0);
  EXPECT_DOUBLE_EQ(c->fy, 310.0);
  EXPECT_FALSE(c->has_distortion());
}

TEST(CameraXml, VispErrorsNameLineAndElement) {
  const std::string text = "<?xml version=\"1.0\"?>\n<root>\n<camera>\n<image_width>640</image_width>\n"
                           "<image_height>480</image_height>\n<model>\n<type>perspectiveProjWithoutDistortion</type>\n"
                           "<px>6OO</px>\n<py>600</py><u0>320</u0><v0>240</v0></model></camera></root>\n";
  auto c = parse_camera(text, "bad.xml");
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().file, "bad.xml");
  EXPECT_EQ(c.error().line, 8);
  EXPECT_EQ(c.error().field, "px");
  EXPECT_NE(c.error().message.find("6OO"), std::string::npos) << c.error().to_string();

  auto unclosed = parse_camera("<root>\n<camera>\n<image_width>640</image_width>\n", "cut.xml");
  ASSERT_FALSE(unclosed);
  EXPECT_NE(unclosed.error().message.find("end of file inside <camera>"), std::string::npos)
      << unclosed.error().to_string();

  auto other = parse_camera("<calibration><fx>1</fx></calibration>", "other.xml");
  ASSERT_FALSE(other);
  EXPECT_NE(other.error().message.find("opencv_storage"), std::string::npos) << other.error().to_string();
}

TEST(CameraXml, OpenCvFileStorageXmlAsOpenCvWritesIt) {
  const fs::path path = fs::temp_directory_path() / ("v4r_cam_" + std::to_string(::getpid()) + ".xml");
  {
    cv::FileStorage f(path.string(), cv::FileStorage::WRITE);
    ASSERT_TRUE(f.isOpened());
    const cv::Mat K = (cv::Mat_<double>(3, 3) << 612.5, 0, 318.25, 0, 611.75, 243.5, 0, 0, 1);
    const cv::Mat D = (cv::Mat_<double>(1, 5) << -0.21, 0.05, 0.001, -0.002, 0.0);
    f << "image_width" << 640 << "image_height" << 480 << "camera_matrix" << K << "distortion_coefficients" << D;
  }
  auto c = load_camera(path.string());
  fs::remove(path);
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->width, 640);
  EXPECT_EQ(c->height, 480);
  EXPECT_DOUBLE_EQ(c->fx, 612.5);
  EXPECT_DOUBLE_EQ(c->fy, 611.75);
  EXPECT_DOUBLE_EQ(c->cx, 318.25);
  EXPECT_DOUBLE_EQ(c->cy, 243.5);
  EXPECT_DOUBLE_EQ(c->dist[0], -0.21);
  EXPECT_DOUBLE_EQ(c->dist[3], -0.002);
}

TEST(CameraXml, OpenCvXmlWithoutDistortionOrSize) {
  const std::string text = R"(<?xml version="1.0"?>
<opencv_storage>
<camera_matrix type_id="opencv-matrix">
  <rows>3</rows>
  <cols>3</cols>
  <dt>d</dt>
  <data>
    600. 0. 320. 0. 600. 240. 0. 0. 1.</data></camera_matrix>
</opencv_storage>
)";
  auto strict = parse_camera(text, "k.xml");
  ASSERT_FALSE(strict);
  EXPECT_EQ(strict.error().field, "image_width");
  auto c = parse_camera(text, "k.xml", CameraFileOptions{.size_optional = true});
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_EQ(c->width, 0);
  EXPECT_EQ(c->height, 0);
  EXPECT_DOUBLE_EQ(c->fx, 600.0);
  EXPECT_FALSE(c->has_distortion());
}

TEST(CameraYaml, MissingDistortionMeansNone) {
  const std::string text =
      "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n"
      "   dt: d\n   data: [ 600., 0., 319.5, 0., 600., 239.5, 0., 0., 1. ]\n";
  auto c = parse_camera(text, "nod.yaml");
  ASSERT_TRUE(c) << c.error().to_string();
  EXPECT_FALSE(c->has_distortion());
}

TEST(CameraYaml, SizeOptionalOnlyWhenBothAreMissing) {
  const std::string k = "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                        "   data: [ 600., 0., 319.5, 0., 600., 239.5, 0., 0., 1. ]\n";
  auto none = parse_camera("%YAML:1.0\n---\n" + k, "k.yaml", CameraFileOptions{.size_optional = true});
  ASSERT_TRUE(none) << none.error().to_string();
  EXPECT_EQ(none->width, 0);
  auto half = parse_camera("%YAML:1.0\n---\nimage_width: 640\n" + k, "k.yaml", CameraFileOptions{.size_optional = true});
  ASSERT_FALSE(half);
  EXPECT_EQ(half.error().field, "image_height");
}

}  // namespace
}  // namespace v4r::io
