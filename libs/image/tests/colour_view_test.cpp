// v4r - robust model-based object tracking. MIT licence.
// Tests of the colour image view: bilinear sampling of the three channels, clamping, strides,
// and the grey conversion, against values computed by hand.
#include "v4r/image/colour_view.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <vector>

namespace v4r::image {
namespace {

/// A w x h B, G, R image with `pad` spare bytes at the end of each row, channel c of pixel (x, y)
/// holding (17 x + 29 y + 71 c) mod 256, a pattern with distinct neighbours.
struct TestImage {
  int w, h, stride;
  std::vector<std::uint8_t> px;
  TestImage(int w_, int h_, int pad) : w(w_), h(h_), stride(3 * w_ + pad), px(static_cast<std::size_t>(stride) * h_, 0xEE) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) px[static_cast<std::size_t>(y) * stride + 3 * x + c] = value(x, y, c);
  }
  static std::uint8_t value(int x, int y, int c) { return static_cast<std::uint8_t>((17 * x + 29 * y + 71 * c) % 256); }
  [[nodiscard]] ColourView view() const { return {px.data(), w, h, stride}; }
};

TEST(ColourView, PixelAccessHonoursStride) {
  const TestImage img(7, 5, 5);
  const ColourView v = img.view();
  EXPECT_FALSE(v.empty());
  EXPECT_TRUE(ColourView{}.empty());
  for (int y = 0; y < img.h; ++y)
    for (int x = 0; x < img.w; ++x)
      for (int c = 0; c < 3; ++c) EXPECT_EQ(v.pixel(x, y)[c], TestImage::value(x, y, c));
}

TEST(ColourView, BilinearSampleMatchesHandComputation) {
  const TestImage img(9, 6, 3);
  const ColourView v = img.view();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> ux(0.0, img.w - 1.001), uy(0.0, img.h - 1.001);
  for (int k = 0; k < 200; ++k) {
    const double x = ux(rng), y = uy(rng);
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const double ax = x - x0, ay = y - y0;
    float bgr[3];
    v.sample(x, y, bgr);
    for (int c = 0; c < 3; ++c) {
      const double expect = (1 - ax) * (1 - ay) * TestImage::value(x0, y0, c) + ax * (1 - ay) * TestImage::value(x0 + 1, y0, c) +
                            (1 - ax) * ay * TestImage::value(x0, y0 + 1, c) + ax * ay * TestImage::value(x0 + 1, y0 + 1, c);
      EXPECT_NEAR(bgr[c], expect, 1e-3) << "x " << x << " y " << y << " c " << c;
    }
  }
  // At pixel centres the sample is the pixel.
  float bgr[3];
  v.sample(4.0, 3.0, bgr);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(bgr[c], TestImage::value(4, 3, c), 1e-4);
}

TEST(ColourView, SampleIsClampedToTheImage) {
  const TestImage img(6, 4, 0);
  const ColourView v = img.view();
  float a[3], b[3];
  v.sample(-5.0, -3.0, a);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], TestImage::value(0, 0, c), 1e-3);
  v.sample(100.0, 100.0, a);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], TestImage::value(5, 3, c), 0.1);  // within 1e-4 px of the corner
  v.sample(2.5, -1.0, a);
  v.sample(2.5, 0.0, b);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-4);
  EXPECT_TRUE(v.contains(0.0, 0.0));
  EXPECT_TRUE(v.contains(5.0, 3.0));
  EXPECT_FALSE(v.contains(5.0, 3.0, 0.5));
  EXPECT_FALSE(v.contains(-0.1, 1.0));
}

TEST(ColourView, GreyConversionIsBt601Luma) {
  EXPECT_EQ(grey_of(0, 0, 0), 0);
  EXPECT_EQ(grey_of(255, 255, 255), 255);
  EXPECT_EQ(grey_of(0, 0, 255), 77);    // pure red: 0.299 * 255 = 76.2 -> 77 in the 8-bit weights
  EXPECT_EQ(grey_of(0, 255, 0), 149);   // pure green: 0.587 * 255 = 149.7
  EXPECT_EQ(grey_of(255, 0, 0), 29);    // pure blue: 0.114 * 255 = 29.1
  std::mt19937 rng(9);
  std::uniform_int_distribution<int> u(0, 255);
  for (int k = 0; k < 1000; ++k) {
    const int b = u(rng), g = u(rng), r = u(rng);
    EXPECT_NEAR(grey_of(static_cast<std::uint8_t>(b), static_cast<std::uint8_t>(g), static_cast<std::uint8_t>(r)),
                0.114 * b + 0.587 * g + 0.299 * r, 1.0);
  }
  const TestImage img(11, 7, 4);
  std::vector<std::uint8_t> out(static_cast<std::size_t>(13) * img.h, 0);
  const ImageView grey = to_grey(img.view(), out.data(), 13);
  ASSERT_FALSE(grey.empty());
  EXPECT_EQ(grey.width, img.w);
  EXPECT_EQ(grey.stride, 13);
  for (int y = 0; y < img.h; ++y)
    for (int x = 0; x < img.w; ++x) {
      const std::uint8_t* p = img.view().pixel(x, y);
      EXPECT_EQ(grey.at(x, y), grey_of(p[0], p[1], p[2]));
    }
  EXPECT_TRUE(to_grey(img.view(), out.data(), img.w - 1).empty());  // stride too small
  EXPECT_TRUE(to_grey(ColourView{}, out.data(), 13).empty());
}

}  // namespace
}  // namespace v4r::image
