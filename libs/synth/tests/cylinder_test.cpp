// v4r - robust model-based object tracking. MIT licence.
// Cylinders: silhouettes (limbs), end disks and rims against their analytic projections.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "render_test_helpers.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::synth {
namespace {

using geometry::PinholeCamera;
using geometry::SE3;
using test::kDeg;
using test::window_median;

RenderOptions clean_grey() {
  RenderOptions o;
  o.noise_sigma = 0.0;
  o.texture_strength = 0.0;
  o.textured_background = false;
  o.colour = false;
  return o;
}

/// A lone cylinder from p1 to p2 (object frame), built feature by feature.
model::Model lone_cylinder(const Eigen::Vector3d& p1, const Eigen::Vector3d& p2, double radius) {
  model::ModelBuilder b("cylinder");
  model::Cylinder c;
  c.p1 = p1;
  c.p2 = p2;
  c.radius = radius;
  b.add_cylinder(c);
  auto m = std::move(b).build();
  EXPECT_TRUE(m.has_value());
  return std::move(m).value();
}

/// Sub-pixel position where the grey level crosses `level` between samples i0 and i1 of a
/// row (horizontal) or column (vertical), by linear interpolation; NaN if it does not.
double crossing(const cv::Mat& grey, bool horizontal, int fixed, int i0, int i1, double level) {
  auto at = [&](int i) -> double {
    return horizontal ? grey.at<std::uint8_t>(fixed, i) : grey.at<std::uint8_t>(i, fixed);
  };
  for (int i = i0; i < i1; ++i) {
    const double a = at(i), b = at(i + 1);
    if ((a - level) * (b - level) <= 0.0 && a != b) return i + (level - a) / (b - a);
  }
  return std::nan("");
}

/// Bisection for the parameter s in [0, 1] where f(s) crosses `target` (f monotonic).
template <typename F>
double solve(F f, double target) {
  double s0 = 0.0, s1 = 1.0;
  const bool increasing = f(1.0) > f(0.0);
  for (int it = 0; it < 60; ++it) {
    const double s = 0.5 * (s0 + s1);
    if ((f(s) < target) == increasing)
      s0 = s;
    else
      s1 = s;
  }
  return 0.5 * (s0 + s1);
}

TEST(Cylinder, LimbsMatchTheAnalyticProjectionToSubPixelAccuracy) {
  const PinholeCamera cam = default_camera();  // with lens distortion
  const Renderer r(cam, clean_grey());
  const double radius = 0.04, length = 0.15;
  const Eigen::Vector3d p1(0, 0, -0.075), p2(0, 0, 0.075);
  const model::Model cyl = lone_cylinder(p1, p2, radius);
  int checked = 0;
  double max_err = 0.0;
  for (const SE3& T : {geometry::look_at(0.45, -40 * kDeg, 25 * kDeg), geometry::look_at(0.5, 70 * kDeg, 35 * kDeg),
                       geometry::look_at(0.4, 160 * kDeg, 15 * kDeg)}) {
    const cv::Mat img = r.render(cyl, T, 0);
    // Limb generators: the tangent planes through the camera centre touch the side along
    // g(h) = a - r m + h d, where m (unit, orthogonal to d) satisfies m . a = r.
    const Eigen::Vector3d a = T * p1, d = (T.rotation() * (p2 - p1)).normalized();
    const Eigen::Vector3d a_perp = a - a.dot(d) * d;
    const double D = a_perp.norm();
    ASSERT_GT(D, radius);
    const Eigen::Vector3d ahat = a_perp / D, bhat = d.cross(ahat);
    const double cb = radius / D, sb = std::sqrt(1.0 - cb * cb);
    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> limbs;  // generator end points
    for (const double sign : {1.0, -1.0}) {
      const Eigen::Vector3d m = cb * ahat + sign * sb * bhat;
      ASSERT_NEAR(m.dot(a), radius, 1e-12);
      limbs.emplace_back(a - radius * m, a - radius * m + length * d);
    }
    auto mid_x = [&](const auto& g) { return cam.project(0.5 * (g.first + g.second)).x(); };
    std::sort(limbs.begin(), limbs.end(), [&](const auto& u, const auto& v) { return mid_x(u) < mid_x(v); });
    for (const auto& [g, left] : {std::pair{limbs.front(), true}, std::pair{limbs.back(), false}}) {
      const Eigen::Vector2d pa = cam.project(g.first), pb = cam.project(g.second);
      const double ylo = std::min(pa.y(), pb.y()), yhi = std::max(pa.y(), pb.y());
      for (const double frac : {0.3, 0.5, 0.7}) {
        const int row = static_cast<int>(std::lround(ylo + frac * (yhi - ylo)));
        const double s = solve([&](double t) { return cam.project(g.first + t * (g.second - g.first)).y(); }, row);
        const double xe = cam.project(g.first + s * (g.second - g.first)).x();
        const int xi = static_cast<int>(std::lround(xe));
        const double bg = window_median(img, left ? xi - 4 : xi + 4, row, 1);
        const double fg = window_median(img, left ? xi + 4 : xi - 4, row, 1);
        ASSERT_GT(std::abs(fg - bg), 15.0) << "no contrast at row " << row;
        const double xc = crossing(img, true, row, xi - 3, xi + 3, 0.5 * (fg + bg));
        ASSERT_FALSE(std::isnan(xc));
        EXPECT_NEAR(xc, xe, 0.3) << "row " << row << (left ? " left" : " right");
        max_err = std::max(max_err, std::abs(xc - xe));
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 18);
  ::testing::Test::RecordProperty("max_limb_error_px", std::to_string(max_err));
}

TEST(Cylinder, EndDiskIsTheEllipseOfTheProjectedCircle) {
  PinholeCamera cam = default_camera();
  cam.dist = {0, 0, 0, 0, 0};  // the image of a circle is then exactly a conic
  const Renderer r(cam, clean_grey());
  const double radius = 0.05;
  const model::Model cyl = lone_cylinder(Eigen::Vector3d(0, 0, -0.02), Eigen::Vector3d::Zero(), radius);
  // The camera is above the top disk and inside the (infinite) cylinder, so only the top disk
  // is visible; it looks away from the axis, so that the disk is seen obliquely, off-centre.
  const SE3 T = geometry::look_at(Eigen::Vector3d(0.02, -0.01, 0.35), Eigen::Vector3d(0.07, 0.05, 0.0));
  const cv::Mat img = r.render(cyl, T, 0);

  // Image conic of the circle: points H (r cos t, r sin t, 1)^T with H = K [e1 e2 c].
  const Eigen::Matrix3d R = T.rotation();
  const Eigen::Vector3d c = T * Eigen::Vector3d::Zero(), e1 = R.col(0), e2 = R.col(1);
  Eigen::Matrix3d K;
  K << cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1;
  Eigen::Matrix3d H;
  H.col(0) = K * e1;
  H.col(1) = K * e2;
  H.col(2) = K * c;
  const Eigen::Matrix3d Hi = H.inverse();
  const Eigen::Matrix3d C = Hi.transpose() * Eigen::Vector3d(1, 1, -radius * radius).asDiagonal() * Hi;
  const Eigen::Vector2d centre = C.topLeftCorner<2, 2>().ldlt().solve(-C.topRightCorner<2, 1>());
  const Eigen::Vector2d projected_centre = cam.project(c);

  // Disk coverage per pixel from the grey level (uniform disk on a uniform background).
  const double bg = RenderOptions{}.background_grey;
  const double disk =
      window_median(img, static_cast<int>(std::lround(centre.x())), static_cast<int>(std::lround(centre.y())), 3);
  ASSERT_GT(disk - bg, 40.0);
  double sw = 0, sx = 0, sy = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const double wgt = std::clamp((img.at<std::uint8_t>(y, x) - bg) / (disk - bg), 0.0, 1.0);
      sw += wgt;
      sx += wgt * x;
      sy += wgt * y;
    }
  const Eigen::Vector2d measured(sx / sw, sy / sw);
  // The disk lies inside the image and is clearly off-centre and oblique: its ellipse centre
  // differs from the projection of the circle's centre.
  for (int k = 0; k < 64; ++k) {
    const double t = 2.0 * std::numbers::pi * k / 64;
    ASSERT_TRUE(cam.in_image(cam.project(T * Eigen::Vector3d(radius * std::cos(t), radius * std::sin(t), 0.0)), 2.0));
  }
  ASSERT_GT((centre - projected_centre).norm(), 0.5);
  EXPECT_LT((measured - centre).norm(), 0.1)
      << "measured " << measured.transpose() << " analytic " << centre.transpose();
  // Its area is the ellipse's (pi a b from the conic).
  const Eigen::Matrix2d A = C.topLeftCorner<2, 2>();
  const double k = centre.dot(A * centre) - C(2, 2);  // (x - x0)^T A (x - x0) = k
  const double area = std::numbers::pi * k / std::sqrt(A.determinant());
  EXPECT_NEAR(sw, area, 0.005 * area);
  ::testing::Test::RecordProperty("disk_centre_error_px", std::to_string((measured - centre).norm()));
  ::testing::Test::RecordProperty("ellipse_vs_projected_centre_px", std::to_string((centre - projected_centre).norm()));
}

TEST(Cylinder, RimsAreSharpAndInPlaceAgainstTheBackgroundAndTheSide) {
  const PinholeCamera cam = default_camera();
  const Renderer r(cam, clean_grey());
  const double radius = 0.05, height = 0.06;
  const model::Model cyl = lone_cylinder(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, height), radius);
  int checked = 0;
  for (const SE3& T : {geometry::look_at(0.5, -30 * kDeg, 35 * kDeg), geometry::look_at(0.45, 100 * kDeg, 50 * kDeg)}) {
    const cv::Mat img = r.render(cyl, T, 0);
    const Eigen::Vector3d top(0, 0, height);
    const int col = static_cast<int>(std::lround(cam.project(T * top).x()));
    // Rim points whose projection falls on this column: the far one (disk above, background
    // beyond) and the near one (disk above, side below).
    auto rim = [&](double t) { return T * (top + radius * Eigen::Vector3d(std::cos(t), std::sin(t), 0.0)); };
    std::vector<double> ys;
    for (int k = 0; k < 720; ++k) {
      const double t0 = 2.0 * std::numbers::pi * k / 720, t1 = 2.0 * std::numbers::pi * (k + 1) / 720;
      const double x0 = cam.project(rim(t0)).x() - col, x1 = cam.project(rim(t1)).x() - col;
      if (x0 * x1 > 0.0) continue;
      const double s = solve([&](double u) { return cam.project(rim(t0 + u * (t1 - t0))).x(); }, col);
      ys.push_back(cam.project(rim(t0 + s * (t1 - t0))).y());
    }
    ASSERT_EQ(ys.size(), 2u);
    std::sort(ys.begin(), ys.end());
    for (const double ye : ys) {
      const int yi = static_cast<int>(std::lround(ye));
      const double above = window_median(img, col, yi - 4, 1), below = window_median(img, col, yi + 4, 1);
      ASSERT_GT(std::abs(above - below), 15.0) << "no contrast at rim y " << ye;
      const double yc = crossing(img, false, col, yi - 3, yi + 3, 0.5 * (above + below));
      ASSERT_FALSE(std::isnan(yc));
      EXPECT_NEAR(yc, ye, 0.3) << "rim at column " << col;
      // Anti-aliased: a single transition pixel at most between the two levels.
      int between = 0;
      for (int y = yi - 3; y <= yi + 3; ++y) {
        const double v = img.at<std::uint8_t>(y, col);
        if (std::abs(v - above) > 3.0 && std::abs(v - below) > 3.0) ++between;
      }
      EXPECT_LE(between, 2);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 4);
}

TEST(Cylinder, SideIsShadedByItsNormalAndTexturedWithoutASeam) {
  const PinholeCamera cam = default_camera();
  RenderOptions opt = clean_grey();
  const model::Model cyl = lone_cylinder(Eigen::Vector3d(0, 0, -0.05), Eigen::Vector3d(0, 0, 0.05), 0.05);
  const SE3 T = geometry::look_at(0.5, 0.0, 10 * kDeg);
  // Untextured: Lambert with the per-pixel normal. The column through the axis sees the normal
  // pointing at the camera (horizontally); a column further right sees it turned.
  const cv::Mat img = Renderer(cam, opt).render(cyl, T, 0);
  const Eigen::Vector3d light = opt.light_dir_cam.normalized();
  const double albedo = 255.0 * 0.85;
  for (const double phi_deg : {0.0, 40.0, -50.0}) {
    // The point of the side at azimuth phi (0: towards the camera, +x in the object frame).
    const double phi = phi_deg * kDeg;
    const Eigen::Vector3d n_obj(std::cos(phi), std::sin(phi), 0.0);
    const Eigen::Vector3d p = T * Eigen::Vector3d(0.05 * n_obj.x(), 0.05 * n_obj.y(), 0.0);
    const Eigen::Vector3d n = T.rotation() * n_obj;
    const double shade = opt.ambient + (1.0 - opt.ambient) * std::max(0.0, n.dot(light));
    const Eigen::Vector2d px = cam.project(p);
    const double v = img.at<std::uint8_t>(static_cast<int>(std::lround(px.y())), static_cast<int>(std::lround(px.x())));
    EXPECT_NEAR(v, albedo * shade, 0.035 * albedo) << "azimuth " << phi_deg;  // albedo varies by 2.5 % per surface
  }
  // Textured: the texture is continuous all around, including where its angle wraps: no
  // gradient on the side exceeds the texture's usual gentle slope.
  opt.texture_strength = 0.25;
  const Renderer tex(cam, opt);
  for (const double az : {0.0, 60.0, 120.0, 180.0, 240.0, 300.0}) {
    const SE3 Ta = geometry::look_at(0.35, az * kDeg, 0.0);
    const cv::Mat t = tex.render(cyl, Ta, 0);
    const Eigen::Vector2d c = cam.project(Ta * Eigen::Vector3d::Zero());
    cv::Mat gx;
    const cv::Rect roi(static_cast<int>(c.x()) - 55, static_cast<int>(c.y()) - 40, 111, 81);  // inside the side
    cv::Sobel(t(roi), gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
    double mx = 0.0;
    cv::minMaxLoc(cv::abs(gx), nullptr, &mx);
    EXPECT_LT(mx, 8.0) << "azimuth " << az;
  }
}

}  // namespace
}  // namespace v4r::synth
