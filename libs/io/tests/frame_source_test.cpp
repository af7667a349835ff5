// v4r - robust model-based object tracking. MIT licence.

#include "v4r/io/frame_source.hpp"

#include "temp_dir.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <random>
#include <string>
#include <vector>

namespace v4r::io {
namespace {

namespace fs = std::filesystem;

using test::TempDir;

/// A 1-channel 8-bit image filled with `value`.
cv::Mat grey(int value, int w = 32, int h = 24) { return cv::Mat(h, w, CV_8UC1, cv::Scalar(value)); }

/// A 3-channel 8-bit image of uniform noise (incompressible, so truncation cuts pixel data).
cv::Mat noise(int w, int h, unsigned seed) {
  cv::Mat img(h, w, CV_8UC3);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> u(0, 255);
  for (int y = 0; y < h; ++y) {
    auto* row = img.ptr<std::uint8_t>(y);
    for (int x = 0; x < 3 * w; ++x) row[x] = static_cast<std::uint8_t>(u(rng));
  }
  return img;
}

/// Reads every frame; fails the test on an error. Returns the frames and their names.
void read_all(FrameSource& src, std::vector<cv::Mat>& frames, std::vector<std::string>& names) {
  for (int guard = 0; guard < 1000; ++guard) {
    cv::Mat f;
    const Expected<bool> r = src.next(f);
    ASSERT_TRUE(r) << r.error().to_string();
    if (!*r) return;
    frames.push_back(f.clone());
    names.push_back(src.current_name());
  }
  FAIL() << "source did not end";
}

TEST(FrameSource, FolderSortedByNameCaseInsensitiveExtensions) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  // Written out of order; only image files count; extensions in any case.
  ASSERT_TRUE(cv::imwrite(dir.file("frame_b.png"), grey(20)));
  ASSERT_TRUE(cv::imwrite(dir.file("frame_c.PNG"), grey(30)));
  ASSERT_TRUE(cv::imwrite(dir.file("frame_a.png"), grey(10)));
  std::ofstream(dir.file("notes.txt")) << "not an image\n";
  fs::create_directory(dir.file("sub.png"));  // a directory with an image-like name is skipped

  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(dir.path());
  ASSERT_TRUE(src) << src.error().to_string();
  EXPECT_EQ((*src)->size_hint(), 3);
  EXPECT_EQ((*src)->current_name(), "");
  std::vector<cv::Mat> frames;
  std::vector<std::string> names;
  read_all(**src, frames, names);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(names[0], dir.file("frame_a.png"));
  EXPECT_EQ(names[1], dir.file("frame_b.png"));
  EXPECT_EQ(names[2], dir.file("frame_c.PNG"));
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(frames[i].type(), CV_8UC1);  // grey stays grey
    EXPECT_EQ(frames[i].cols, 32);
    EXPECT_EQ(frames[i].rows, 24);
    EXPECT_EQ(frames[i].at<std::uint8_t>(5, 7), 10 * (i + 1));
  }
  // At the end, next() keeps returning false.
  cv::Mat f;
  const Expected<bool> again = (*src)->next(f);
  ASSERT_TRUE(again);
  EXPECT_FALSE(*again);
}

TEST(FrameSource, ColourStaysBgrAndSixteenBitBecomesEightBit) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  cv::Mat colour(10, 12, CV_8UC3, cv::Scalar(10, 100, 200));
  ASSERT_TRUE(cv::imwrite(dir.file("0_colour.png"), colour));
  cv::Mat deep(10, 12, CV_16UC1, cv::Scalar(257 * 100));
  deep.at<std::uint16_t>(0, 0) = 65535;
  ASSERT_TRUE(cv::imwrite(dir.file("1_deep.png"), deep));
  cv::Mat bgra(10, 12, CV_8UC4, cv::Scalar(1, 2, 3, 128));
  ASSERT_TRUE(cv::imwrite(dir.file("2_alpha.png"), bgra));

  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(dir.path());
  ASSERT_TRUE(src) << src.error().to_string();
  std::vector<cv::Mat> frames;
  std::vector<std::string> names;
  read_all(**src, frames, names);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].type(), CV_8UC3);
  EXPECT_EQ(frames[0].at<cv::Vec3b>(3, 4), cv::Vec3b(10, 100, 200));
  EXPECT_EQ(frames[1].type(), CV_8UC1);
  EXPECT_EQ(frames[1].at<std::uint8_t>(3, 4), 100);
  EXPECT_EQ(frames[1].at<std::uint8_t>(0, 0), 255);
  EXPECT_EQ(frames[2].type(), CV_8UC3);  // alpha dropped
  EXPECT_EQ(frames[2].at<cv::Vec3b>(3, 4), cv::Vec3b(1, 2, 3));
}

TEST(FrameSource, PatternStartingAtOneStopsAtFirstGap) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  for (int i : {1, 2, 3, 4, 6}) {  // 5 is missing: frame 6 is not reached
    ASSERT_TRUE(cv::imwrite(dir.file(fmt::format("img_{:06d}.png", i)), grey(i)));
  }
  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(dir.file("img_%06d.png"));
  ASSERT_TRUE(src) << src.error().to_string();
  EXPECT_EQ((*src)->size_hint(), 4);
  std::vector<cv::Mat> frames;
  std::vector<std::string> names;
  read_all(**src, frames, names);
  ASSERT_EQ(frames.size(), 4u);
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(names[k], dir.file(fmt::format("img_{:06d}.png", k + 1)));
    EXPECT_EQ(frames[k].at<std::uint8_t>(0, 0), k + 1);
  }
}

TEST(FrameSource, PatternStartingAtZeroWithoutPadding) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  for (int i = 0; i <= 11; ++i) ASSERT_TRUE(cv::imwrite(dir.file(fmt::format("{}.pgm", i)), grey(5 * i)));
  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(dir.file("%d.pgm"));
  ASSERT_TRUE(src) << src.error().to_string();
  EXPECT_EQ((*src)->size_hint(), 12);
  std::vector<cv::Mat> frames;
  std::vector<std::string> names;
  read_all(**src, frames, names);
  ASSERT_EQ(frames.size(), 12u);
  EXPECT_EQ(names[10], dir.file("10.pgm"));
  EXPECT_EQ(frames[11].at<std::uint8_t>(1, 1), 55);
}

TEST(FrameSource, MissingPatternIsAnError) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  ASSERT_TRUE(cv::imwrite(dir.file("img_000002.png"), grey(1)));  // neither 0 nor 1
  const std::string pattern = dir.file("img_%06d.png");
  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(pattern);
  ASSERT_FALSE(src);
  EXPECT_NE(src.error().message.find(pattern), std::string::npos) << src.error().to_string();
  EXPECT_NE(src.error().message.find("no files match"), std::string::npos) << src.error().to_string();
}

TEST(FrameSource, EmptyFolderIsAnError) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  std::ofstream(dir.file("readme.md")) << "no images here\n";
  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(dir.path());
  ASSERT_FALSE(src);
  EXPECT_EQ(src.error().message, "no images in " + dir.path());
}

TEST(FrameSource, TruncatedPngIsAnErrorNamingIt) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  ASSERT_TRUE(cv::imwrite(dir.file("a.png"), noise(64, 48, 1)));
  const std::string bad = dir.file("b.png");
  ASSERT_TRUE(cv::imwrite(bad, noise(64, 48, 2)));
  fs::resize_file(bad, fs::file_size(bad) / 2);
  ASSERT_TRUE(cv::imwrite(dir.file("c.png"), noise(64, 48, 3)));

  // Alone: a one-frame source whose only frame fails.
  {
    Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(bad);
    ASSERT_TRUE(src) << src.error().to_string();
    EXPECT_EQ((*src)->size_hint(), 1);
    cv::Mat f;
    const Expected<bool> r = (*src)->next(f);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().file, bad);
    EXPECT_NE(r.error().message.find(bad), std::string::npos) << r.error().to_string();
    EXPECT_EQ((*src)->current_name(), bad);
  }
  // In a folder: the good frames around it are still delivered.
  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(dir.path());
  ASSERT_TRUE(src) << src.error().to_string();
  cv::Mat f;
  Expected<bool> r = (*src)->next(f);
  ASSERT_TRUE(r && *r);
  EXPECT_EQ(f.type(), CV_8UC3);
  r = (*src)->next(f);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().file, bad);
  r = (*src)->next(f);
  ASSERT_TRUE(r && *r);
  EXPECT_EQ((*src)->current_name(), dir.file("c.png"));
  EXPECT_EQ(cv::norm(f, noise(64, 48, 3), cv::NORM_INF), 0.0);  // lossless
  r = (*src)->next(f);
  ASSERT_TRUE(r);
  EXPECT_FALSE(*r);
}

TEST(FrameSource, SingleImageFile) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("still.BMP");
  ASSERT_TRUE(cv::imwrite(path, noise(20, 10, 4)));
  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(path);
  ASSERT_TRUE(src) << src.error().to_string();
  std::vector<cv::Mat> frames;
  std::vector<std::string> names;
  read_all(**src, frames, names);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(names[0], path);
  EXPECT_EQ(cv::norm(frames[0], noise(20, 10, 4), cv::NORM_INF), 0.0);
}

TEST(FrameSource, MjpgVideoReadBackWithTheRightCount) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("clip.avi");
  constexpr int kFrames = 7;
  {
    cv::VideoWriter writer(path, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 25.0, cv::Size(64, 48), true);
    ASSERT_TRUE(writer.isOpened());
    for (int i = 0; i < kFrames; ++i) writer.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(30 * i, 30 * i, 30 * i)));
  }
  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(path);
  ASSERT_TRUE(src) << src.error().to_string();
  EXPECT_EQ((*src)->size_hint(), kFrames);
  std::vector<cv::Mat> frames;
  std::vector<std::string> names;
  read_all(**src, frames, names);
  ASSERT_EQ(static_cast<int>(frames.size()), kFrames);
  for (int i = 0; i < kFrames; ++i) {
    EXPECT_EQ(names[i], path + "#" + std::to_string(i));
    EXPECT_EQ(frames[i].type(), CV_8UC3);
    EXPECT_EQ(frames[i].cols, 64);
    EXPECT_EQ(frames[i].rows, 48);
    EXPECT_NEAR(cv::mean(frames[i])[0], 30.0 * i, 3.0) << "frame " << i;  // JPEG is lossy
  }
}

TEST(FrameSource, UnopenableVideoIsAnError) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("garbage.avi");
  std::ofstream(path, std::ios::binary) << "this is not a video file at all\n";
  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(path);
  ASSERT_FALSE(src);
  EXPECT_EQ(src.error().message, "cannot open video " + path);
}

TEST(FrameSource, NonexistentPathIsAnError) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("nothing_here.mp4");
  Expected<std::unique_ptr<FrameSource>> src = FrameSource::open(path);
  ASSERT_FALSE(src);
  EXPECT_EQ(src.error().message, "input not found: " + path);
  EXPECT_EQ(src.error().file, path);
  src = FrameSource::open(dir.file("no_folder/%04d.png"));  // a pattern whose folder is missing
  ASSERT_FALSE(src);
  src = FrameSource::open(dir.file("bad_%q.png"));  // not an integer conversion: a plain missing path
  ASSERT_FALSE(src);
  EXPECT_EQ(src.error().message, "input not found: " + dir.file("bad_%q.png"));
}

TEST(FrameSource, AsViewSharesPixels) {
  const cv::Mat img = grey(77, 16, 8);
  const image::ImageView v = as_view(img);
  EXPECT_EQ(v.width, 16);
  EXPECT_EQ(v.height, 8);
  EXPECT_EQ(v.stride, static_cast<int>(img.step[0]));
  EXPECT_EQ(v.data, img.data);
  EXPECT_EQ(v.at(3, 5), 77);
}

}  // namespace
}  // namespace v4r::io
