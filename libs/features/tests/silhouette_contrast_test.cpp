// v4r - robust model-based object tracking. MIT licence.
#include "v4r/features/silhouette_contrast.hpp"

#include <gtest/gtest.h>

#include <array>
#include <random>
#include <vector>

#include "synthetic_images.hpp"

using namespace v4r;
using namespace v4r::features;
using namespace v4r::features::test_images;

namespace {

constexpr int kW = 240, kH = 200;
using Colour3 = std::array<int, 3>;

/// A green box face (x 60..180, y 50..150) on a grey table, a dark green band across the face
/// (y 80..90), BGR with noise.
std::vector<std::uint8_t> scene_bgr(double noise, Colour3 table = {120, 120, 120}) {
  std::vector<std::uint8_t> img(static_cast<std::size_t>(kW * kH * 3));
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, noise);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      Colour3 c = table;
      if (x >= 60 && x < 180 && y >= 50 && y < 150) c = y >= 80 && y < 90 ? Colour3{40, 125, 55} : Colour3{50, 160, 70};
      for (int k = 0; k < 3; ++k)
        img[static_cast<std::size_t>((y * kW + x) * 3 + k)] =
            static_cast<std::uint8_t>(std::clamp(c[static_cast<std::size_t>(k)] + n(rng), 0.0, 255.0));
    }
  return img;
}

std::vector<std::uint8_t> grey_of_bgr(const std::vector<std::uint8_t>& bgr) {
  std::vector<std::uint8_t> g(bgr.size() / 3);
  for (std::size_t i = 0; i < g.size(); ++i) g[i] = image::grey_of(bgr[3 * i], bgr[3 * i + 1], bgr[3 * i + 2]);
  return g;
}

/// The leak of the rectangle outline x0..x1, y0..y1 (pixel edges), object inside.
double leak(SilhouetteContrast& c, const image::ImageView& grey, const image::ColourView& colour, double x0, double y0,
            double x1, double y1) {
  c.reset();
  const Eigen::Vector2d p[4] = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  const Eigen::Vector2d out[4] = {{0, -1}, {1, 0}, {0, 1}, {-1, 0}};  // top, right, bottom, left
  for (int e = 0; e < 4; ++e) {
    const Eigen::Vector2d a = p[e], b = p[(e + 1) % 4];
    const int k = static_cast<int>((b - a).norm() / 6.0);
    for (int i = 0; i < k; ++i) c.add_point(grey, colour, a + ((i + 0.5) / k) * (b - a), out[e]);
  }
  c.finish();
  return c.samples() > 0 ? static_cast<double>(c.leaked()) / c.samples() : -1.0;
}

}  // namespace

TEST(SilhouetteContrast, TheRealOutlineLeaksNothingAPoseNestedOnTheTextureLeaks) {
  const auto bgr = scene_bgr(3.0);
  const auto grey = grey_of_bgr(bgr);
  const image::ImageView g = view_of(grey, kW, kH);
  const image::ColourView c = colour_view_of(bgr, kW, kH);
  SilhouetteContrast sc;
  EXPECT_LE(leak(sc, g, c, 59.5, 49.5, 179.5, 149.5), 0.02);
  EXPECT_GT(sc.samples(), 60);
  // A smaller outline whose top lies on the band's lower edge, the rest on the real edges: its
  // top side leaks (band and face are both green), a quarter of the outline or so.
  const double nested = leak(sc, g, c, 59.5, 89.5, 179.5, 149.5);
  EXPECT_GE(nested, 0.2);
  EXPECT_LE(nested, 0.45);
  // An outline well inside the face: everything outside it is face.
  EXPECT_GE(leak(sc, g, c, 80.0, 100.0, 160.0, 135.0), 0.95);
  // reset() clears the count: the real outline again.
  EXPECT_LE(leak(sc, g, c, 59.5, 49.5, 179.5, 149.5), 0.02);
}

TEST(SilhouetteContrast, GreyImagesUseTheBrightnessAlone) {
  const auto bgr = scene_bgr(2.0);
  const auto grey = grey_of_bgr(bgr);
  SilhouetteContrast sc;
  // Green face (grey ~ 123) on a dark table (grey 50): told apart by brightness.
  const auto dark = grey_of_bgr(scene_bgr(2.0, {50, 50, 50}));
  EXPECT_LE(leak(sc, view_of(dark, kW, kH), {}, 59.5, 49.5, 179.5, 149.5), 0.02);
  EXPECT_GE(leak(sc, view_of(dark, kW, kH), {}, 80.0, 100.0, 160.0, 135.0), 0.95);
  // The same face on a table of its own grey level leaks in grey, not in colour (a magenta
  // table: other chromaticity, about the same luma).
  const Colour3 magenta{150, 95, 160};
  const auto m_bgr = scene_bgr(2.0, magenta);
  const auto m_grey = grey_of_bgr(m_bgr);
  EXPECT_GE(leak(sc, view_of(m_grey, kW, kH), {}, 59.5, 49.5, 179.5, 149.5), 0.5);
  EXPECT_LE(leak(sc, view_of(m_grey, kW, kH), colour_view_of(m_bgr, kW, kH), 59.5, 49.5, 179.5, 149.5), 0.05);
  (void)grey;
}

TEST(SilhouetteContrast, SamplesOutsideTheImageAreSkippedAndNothingIsCountedWithoutSamples) {
  const auto bgr = scene_bgr(1.0);
  const auto grey = grey_of_bgr(bgr);
  SilhouetteContrast sc;
  // An outline along the image border: the outside samples fall off the image.
  EXPECT_EQ(leak(sc, view_of(grey, kW, kH), colour_view_of(bgr, kW, kH), 0.0, 0.0, kW - 1.0, kH - 1.0), -1.0);
  EXPECT_EQ(sc.leaked(), 0);
  sc.reset();
  sc.add_point(view_of(grey, kW, kH), {}, Eigen::Vector2d(std::nan(""), 5.0), Eigen::Vector2d(1.0, 0.0));
  sc.finish();
  EXPECT_EQ(sc.samples(), 0);
}

namespace {

struct Segment {
  Eigen::Vector2d a, b, outward;
};

/// The leak of an outline given as segments, each its own group (or all one group).
double leak_of_segments(SilhouetteContrast& c, const image::ColourView& colour, const std::vector<Segment>& segs,
                        bool own_groups) {
  c.reset();
  for (std::size_t s = 0; s < segs.size(); ++s) {
    const int k = static_cast<int>((segs[s].b - segs[s].a).norm() / 6.0);
    for (int i = 0; i < k; ++i)
      c.add_point({}, colour, segs[s].a + ((i + 0.5) / k) * (segs[s].b - segs[s].a), segs[s].outward,
                  SilhouetteContrast::kUnbounded, own_groups ? static_cast<std::uint32_t>(s) : 0u);
  }
  c.finish();
  return c.samples() > 0 ? static_cast<double>(c.leaked()) / c.samples() : -1.0;
}

}  // namespace

TEST(SilhouetteContrast, EachEdgeJudgedByItsOwnFaceALitFaceBesideAShadedOneStandsOut) {
  // A block on a dark table (60, 60, 60): its lit face x 60..150 beige, its shaded face x 150..180
  // the table's own grey. Its outline in pieces, each piece along one face.
  std::vector<std::uint8_t> bgr(static_cast<std::size_t>(kW * kH * 3));
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 2.0);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      Colour3 c{60, 60, 60};
      if (y >= 50 && y < 150 && x >= 60 && x < 150) c = {150, 190, 215};
      for (int k = 0; k < 3; ++k)
        bgr[static_cast<std::size_t>((y * kW + x) * 3 + k)] =
            static_cast<std::uint8_t>(std::clamp(c[static_cast<std::size_t>(k)] + noise(rng), 0.0, 255.0));
    }
  const image::ColourView colour = colour_view_of(bgr, kW, kH);
  const double t = 49.5, b = 149.5, l = 59.5, m = 149.5, r = 179.5;
  const std::vector<Segment> outline{{{l, t}, {m, t}, {0, -1}}, {{m, t}, {r, t}, {0, -1}}, {{r, t}, {r, b}, {1, 0}},
                                     {{r, b}, {m, b}, {0, 1}},  {{m, b}, {l, b}, {0, 1}},  {{l, b}, {l, t}, {-1, 0}}};
  // The shaded face's pieces (30 + 100 + 30 of 440 px) leak: their inside is the table's grey.
  SilhouetteContrast all;
  SilhouetteContrastParams gp;
  gp.min_group_samples = 12;
  SilhouetteContrast grouped(gp);
  const double leak_grouped = leak_of_segments(grouped, colour, outline, true);
  EXPECT_GE(leak_grouped, 0.25);
  EXPECT_LE(leak_grouped, 0.45);
  // Compared with all inside colours at once, the table beside the lit face looks like the
  // object too (the shaded face put its grey among the inside colours): nearly all leaks.
  EXPECT_GE(leak_of_segments(all, colour, outline, true), 0.9);
  EXPECT_GE(leak_of_segments(grouped, colour, outline, false), 0.9);  // one group: the same
  // A pose nested in the lit face still leaks everything, piece by piece.
  const std::vector<Segment> nested{{{80, 70}, {130, 70}, {0, -1}}, {{130, 70}, {130, 130}, {1, 0}},
                                    {{130, 130}, {80, 130}, {0, 1}}, {{80, 130}, {80, 70}, {-1, 0}}};
  EXPECT_GE(leak_of_segments(grouped, colour, nested, true), 0.95);
}
