// v4r - robust model-based object tracking. MIT licence.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "render_test_helpers.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::synth {
namespace {

using geometry::PinholeCamera;
using geometry::SE3;
using test::window_median;

model::Model parse(const std::string& cao, const std::string& name) {
  auto m = model::parse_cao(cao, name);
  if (!m) ADD_FAILURE() << m.error().to_string();
  return std::move(m).value();
}

/// Camera `dist` metres from the object origin, looking at it from `elevation` above the
/// object's xy plane and `azimuth` from the -y axis towards +x (degrees).
SE3 view(double dist, double elevation_deg, double azimuth_deg) {
  const double el = elevation_deg * std::numbers::pi / 180.0, az = azimuth_deg * std::numbers::pi / 180.0;
  const Eigen::Vector3d eye =
      dist * Eigen::Vector3d(std::cos(el) * std::sin(az), -std::cos(el) * std::cos(az), std::sin(el));
  return geometry::look_at(eye, Eigen::Vector3d::Zero());
}

RenderOptions clean_options() {
  RenderOptions o;
  o.noise_sigma = 0.0;
  o.texture_strength = 0.0;
  o.textured_background = false;
  return o;
}

Eigen::Vector3d face_centroid(const model::Model& m, const model::Face& f) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (model::Index j : f.loop) c += m.junctions()[j].p;
  return c / static_cast<double>(f.loop.size());
}

bool front_facing(const model::Model& m, const model::Face& f, const SE3& T) {
  const Eigen::Vector3d n = T.rotation() * f.normal;
  return n.dot(T * face_centroid(m, f)) < 0.0;
}

/// A box built feature by feature (independent of the .cao reader), one colour per face.
model::Model coloured_box() {
  model::ModelBuilder b("coloured box");
  const double a = 0.10, bb = 0.075, c = 0.05;
  const std::vector<Eigen::Vector3d> p{{-a, -bb, -c}, {a, -bb, -c}, {a, bb, -c}, {-a, bb, -c},
                                       {-a, -bb, c},  {a, -bb, c},  {a, bb, c},  {-a, bb, c}};
  for (const auto& q : p) b.add_junction(q);
  const std::vector<std::vector<model::Index>> loops{{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                                     {2, 3, 7, 6}, {1, 2, 6, 5}, {3, 0, 4, 7}};
  const std::vector<Eigen::Vector3f> colours{{0.9f, 0.2f, 0.2f}, {0.8f, 0.8f, 0.3f}, {0.2f, 0.7f, 0.9f},
                                             {0.5f, 0.9f, 0.5f}, {0.9f, 0.6f, 0.1f}, {0.6f, 0.3f, 0.8f}};
  for (std::size_t i = 0; i < loops.size(); ++i) {
    model::Attributes attr;
    attr.colour = colours[i];
    EXPECT_TRUE(b.add_face(loops[i], attr).has_value());
  }
  auto m = std::move(b).build();
  EXPECT_TRUE(m.has_value());
  return std::move(m).value();
}

TEST(Renderer, FaceCentresHaveTheShadedFaceColourAndTheRestIsBackground) {
  const PinholeCamera cam = default_camera();
  const RenderOptions opt = clean_options();
  const Renderer r(cam, opt);
  const model::Model box = coloured_box();
  const Eigen::Vector3d light = opt.light_dir_cam.normalized();
  for (const SE3& T : {view(0.6, 45, 30), view(0.5, 35, -50), view(0.7, 60, 150)}) {
    const cv::Mat img = r.render(box, T, 0);
    ASSERT_EQ(img.type(), CV_8UC3);
    ASSERT_EQ(img.cols, 640);
    ASSERT_EQ(img.rows, 480);
    int checked = 0;
    for (const model::Face& f : box.faces()) {
      if (!front_facing(box, f, T)) continue;
      const Eigen::Vector2d px = cam.project(T * face_centroid(box, f));
      const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
      const double shade = opt.ambient + (1.0 - opt.ambient) * std::max(0.0, (T.rotation() * f.normal).dot(light));
      const cv::Vec3b v = img.at<cv::Vec3b>(y, x);
      const Eigen::Vector3f& rgb = *f.attr.colour;
      EXPECT_NEAR(v[0], 255.0 * rgb.z() * shade, 1.0) << "face " << f.attr.name;
      EXPECT_NEAR(v[1], 255.0 * rgb.y() * shade, 1.0);
      EXPECT_NEAR(v[2], 255.0 * rgb.x() * shade, 1.0);
      ++checked;
    }
    EXPECT_GE(checked, 2);
    // Far from the box (its projection is within ~150 px of the centre): uniform background.
    const int g = static_cast<int>(std::lround(opt.background_grey));
    for (const cv::Point p :
         {cv::Point(5, 5), cv::Point(634, 5), cv::Point(5, 474), cv::Point(634, 474), cv::Point(60, 240)})
      EXPECT_EQ(img.at<cv::Vec3b>(p), cv::Vec3b(g, g, g)) << p;
  }
}

/// Finds, on `row`, the sub-pixel position where the grey level crosses `level` between
/// columns x0 and x1 (linear interpolation between pixel centres); NaN if it does not.
double crossing(const cv::Mat& grey, int row, int x0, int x1, double level) {
  for (int x = x0; x < x1; ++x) {
    const double a = grey.at<std::uint8_t>(row, x), b = grey.at<std::uint8_t>(row, x + 1);
    if ((a - level) * (b - level) <= 0.0 && a != b) return x + (level - a) / (b - a);
  }
  return std::nan("");
}

TEST(Renderer, SilhouetteMatchesTheProjectedOutlineToSubPixelAccuracy) {
  const PinholeCamera cam = default_camera();  // with lens distortion
  RenderOptions opt = clean_options();
  opt.colour = false;
  const Renderer r(cam, opt);
  const model::Model box = parse(box_cao(), "box.cao");
  int checked = 0;
  double max_err = 0.0;
  for (const SE3& T : {view(0.6, 40, 30), view(0.45, 30, -20), view(0.55, 50, 65)}) {
    const cv::Mat img = r.render(box, T, 0);
    // Vertical box edges (junctions differing in z only); the leftmost and rightmost ones are
    // silhouette edges against the background.
    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> verticals;
    for (const model::LineEdge& e : box.lines()) {
      const Eigen::Vector3d a = box.junctions()[e.a].p, b = box.junctions()[e.b].p;
      if (std::abs(a.x() - b.x()) < 1e-9 && std::abs(a.y() - b.y()) < 1e-9) verticals.emplace_back(a, b);
    }
    ASSERT_EQ(verticals.size(), 4u);
    auto mid_x = [&](const auto& e) { return cam.project(T * (0.5 * (e.first + e.second))).x(); };
    std::sort(verticals.begin(), verticals.end(), [&](const auto& u, const auto& v) { return mid_x(u) < mid_x(v); });
    for (const auto& [e, left] : {std::pair{verticals.front(), true}, std::pair{verticals.back(), false}}) {
      const Eigen::Vector2d pa = cam.project(T * e.first), pb = cam.project(T * e.second);
      const double ylo = std::min(pa.y(), pb.y()), yhi = std::max(pa.y(), pb.y());
      for (double frac : {0.3, 0.5, 0.7}) {
        const int row = static_cast<int>(std::lround(ylo + frac * (yhi - ylo)));
        // Point of the 3-D edge that projects onto this row (bisection; the projection is monotonic).
        double s0 = 0.0, s1 = 1.0;
        const bool increasing = pb.y() > pa.y();
        for (int it = 0; it < 60; ++it) {
          const double s = 0.5 * (s0 + s1);
          const double yy = cam.project(T * (e.first + s * (e.second - e.first))).y();
          if ((yy < row) == increasing)
            s0 = s;
          else
            s1 = s;
        }
        const double xe = cam.project(T * (e.first + 0.5 * (s0 + s1) * (e.second - e.first))).x();
        const int xi = static_cast<int>(std::lround(xe));
        const double bg = left ? window_median(img, xi - 4, row, 1) : window_median(img, xi + 4, row, 1);
        const double fg = left ? window_median(img, xi + 4, row, 1) : window_median(img, xi - 4, row, 1);
        ASSERT_GT(std::abs(fg - bg), 20.0) << "no contrast at row " << row;
        const double xc = crossing(img, row, xi - 3, xi + 3, 0.5 * (fg + bg));
        ASSERT_FALSE(std::isnan(xc));
        EXPECT_NEAR(xc, xe, 0.3) << "row " << row << (left ? " left" : " right");
        max_err = std::max(max_err, std::abs(xc - xe));
        ++checked;
      }
    }
  }
  EXPECT_EQ(checked, 18);
  ::testing::Test::RecordProperty("max_silhouette_error_px", std::to_string(max_err));
}

TEST(Renderer, DeterministicForSeedAndFrame) {
  const PinholeCamera cam = default_camera();
  const model::Model box = parse(box_cao(), "box.cao");
  const SE3 T = view(0.6, 45, 30);
  const Renderer r1(cam), r2(cam);
  const cv::Mat a = r1.render(box, T, 3), b = r2.render(box, T, 3), c = r1.render(box, T, 4);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0.0);  // different frame, different noise
  // Noise level as requested (background is smooth: differences of two frames have 2 sigma^2).
  cv::Mat d;
  cv::subtract(a, c, d, cv::noArray(), CV_32F);
  cv::Scalar mean, sd;
  cv::meanStdDev(d.reshape(1), mean, sd);
  EXPECT_NEAR(sd[0], std::sqrt(2.0) * RenderOptions{}.noise_sigma, 0.3);
  RenderOptions other;
  other.seed = 8;
  const Renderer r3(cam, other);
  EXPECT_GT(cv::norm(a, r3.render(box, T, 3), cv::NORM_L1), 0.0);
}

TEST(Renderer, DefaultLookSeparatesFacesAndBackground) {
  const PinholeCamera cam = default_camera();
  RenderOptions opt;
  opt.colour = false;
  const Renderer r(cam, opt);
  const model::Model box = parse(box_cao(), "box.cao");
  const SE3 T = view(0.6, 45, 30);
  const cv::Mat img = r.render(box, T, 0);
  std::vector<double> levels;
  for (const model::Face& f : box.faces()) {
    if (!front_facing(box, f, T)) continue;
    const Eigen::Vector2d px = cam.project(T * face_centroid(box, f));
    levels.push_back(window_median(img, static_cast<int>(px.x()), static_cast<int>(px.y()), 6));
  }
  ASSERT_EQ(levels.size(), 3u);
  for (const cv::Point p : {cv::Point(60, 60), cv::Point(580, 60), cv::Point(60, 420), cv::Point(580, 420)})
    levels.push_back(window_median(img, p.x, p.y, 6));
  for (std::size_t i = 0; i < 3; ++i)
    for (std::size_t j = i + 1; j < levels.size(); ++j)
      EXPECT_GE(std::abs(levels[i] - levels[j]), 25.0)
          << "levels " << i << " and " << j << ": " << levels[i] << " " << levels[j];
}

TEST(Renderer, TextureIsVisibleButWeakerThanEdges) {
  const PinholeCamera cam = default_camera();
  RenderOptions opt;
  opt.colour = false;
  opt.noise_sigma = 0.0;
  const Renderer r(cam, opt);
  const model::Model box = parse(box_cao(), "box.cao");
  const SE3 T = view(0.5, 45, 30);
  const cv::Mat img = r.render(box, T, 0);
  cv::Mat gx, gy, mag;
  cv::Sobel(img, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
  cv::Sobel(img, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
  cv::magnitude(gx, gy, mag);
  double interior_max = 0.0, interior_sd = 0.0;
  int faces = 0;
  for (const model::Face& f : box.faces()) {
    if (!front_facing(box, f, T)) continue;
    const Eigen::Vector2d px = cam.project(T * face_centroid(box, f));
    const cv::Rect roi(static_cast<int>(px.x()) - 7, static_cast<int>(px.y()) - 7, 15, 15);
    double mx = 0.0;
    cv::minMaxLoc(mag(roi), nullptr, &mx);
    cv::Scalar mean, sd;
    cv::meanStdDev(img(roi), mean, sd);
    interior_max = std::max(interior_max, mx);
    interior_sd += sd[0];
    ++faces;
  }
  ASSERT_EQ(faces, 3);
  // Edges between faces and against the background are steps of >= 25 grey levels per ~1 px
  // (gradient >= ~20 with this Sobel scale); the texture is a gentle variation.
  EXPECT_LT(interior_max, 8.0);
  EXPECT_GT(interior_sd / faces, 1.5);  // but visible
  ::testing::Test::RecordProperty("texture_max_gradient", std::to_string(interior_max));
  ::testing::Test::RecordProperty("texture_mean_sd", std::to_string(interior_sd / faces));
}

TEST(Renderer, TextureMovesWithTheObject) {
  PinholeCamera cam = default_camera();
  cam.dist = {0, 0, 0, 0, 0};  // a translation parallel to the image is then an exact pixel shift
  RenderOptions opt;
  opt.noise_sigma = 0.0;
  opt.colour = false;
  const Renderer r(cam, opt);
  const model::Model box = parse(box_cao(), "box.cao");
  // Front face (y = -0.075) parallel to the image plane, 0.425 m away.
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  const double depth = 0.5 - 0.075;
  const int k = 7;
  const SE3 T1(R, Eigen::Vector3d(-0.01, 0.0, 0.5));
  const SE3 T2(R, Eigen::Vector3d(-0.01 + k * depth / cam.fx, 0.0, 0.5));
  const cv::Mat a = r.render(box, T1, 0), b = r.render(box, T2, 0);
  const cv::Rect patch(290, 215, 40, 40);  // inside the front face in both images
  const cv::Rect shifted = patch + cv::Point(k, 0);
  const double moved = cv::norm(a(patch), b(shifted), cv::NORM_L1) / patch.area();
  const double fixed = cv::norm(a(patch), b(patch), cv::NORM_L1) / patch.area();
  cv::Scalar mean, sd;
  cv::meanStdDev(a(patch), mean, sd);
  EXPECT_GT(sd[0], 1.5);              // there is texture
  EXPECT_LT(moved, 0.3);              // it moved with the object (only rounding differences)
  EXPECT_GT(fixed, 3 * moved + 0.5);  // and is not attached to the image
}

TEST(Renderer, GreyAndColourAgree) {
  const PinholeCamera cam = default_camera();
  RenderOptions c = clean_options();
  RenderOptions g = c;
  g.colour = false;
  const model::Model ship = parse(ship_mockup_cao(), "ship_mockup.cao");
  const SE3 T = view(0.7, 45, 35);
  const cv::Mat colour = Renderer(cam, c).render(ship, T, 0), grey = Renderer(cam, g).render(ship, T, 0);
  ASSERT_EQ(grey.type(), CV_8UC1);
  cv::Mat converted;
  cv::cvtColor(colour, converted, cv::COLOR_BGR2GRAY);
  EXPECT_LE(cv::norm(converted, grey, cv::NORM_INF), 1.0);
}

TEST(Renderer, ObjectBehindOrPartlyBehindTheCameraIsClipped) {
  const PinholeCamera cam = default_camera();
  const Renderer r(cam, clean_options());
  const model::Model box = parse(box_cao(), "box.cao");
  // Entirely behind the camera: background only.
  const int g = static_cast<int>(std::lround(RenderOptions{}.background_grey));
  const cv::Mat uniform(cam.height, cam.width, CV_8UC3, cv::Scalar(g, g, g));
  const cv::Mat behind = r.render(box, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, -0.5)), 0);
  EXPECT_EQ(cv::norm(behind, uniform, cv::NORM_INF), 0.0);
  // The box's front face (y = -0.075) crosses the image plane: it is clipped, and drawn below
  // the image centre (camera y down).
  const cv::Mat through = r.render(box, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0.1, 0.02)), 0);
  cv::Mat diff;
  cv::absdiff(through, uniform, diff);
  cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
  // Its clipped part spans z in (0, 0.07] m at y = 0.025 m: image rows below ~450.
  EXPECT_GT(cv::countNonZero(diff.rowRange(455, cam.height)), cam.width * 20);
  EXPECT_EQ(cv::countNonZero(diff.rowRange(0, 440)), 0);
}

TEST(Renderer, TimePerFrame) {
  const PinholeCamera cam = default_camera();
  const Renderer r(cam);
  const model::Model ship = parse(ship_mockup_cao(), "ship_mockup.cao");
  const model::Model box = parse(box_cao(), "box.cao");
  TrajectorySpec spec;
  spec.T0 = view(0.6, 45, 35);
  spec.frames = 20;
  const auto traj = make_trajectory(spec);
  auto time_ms = [&](const model::Model& m) {
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < spec.frames; ++i) (void)r.render(m, traj[static_cast<std::size_t>(i)], i);
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / spec.frames;
  };
  const double ship_ms = time_ms(ship), box_ms = time_ms(box);
  ::testing::Test::RecordProperty("render_ms_per_frame_ship", std::to_string(ship_ms));
  ::testing::Test::RecordProperty("render_ms_per_frame_box", std::to_string(box_ms));
  // Pictures for a human look (not part of the assertions).
  cv::imwrite("/tmp/synth_ship.png", r.render(ship, spec.T0, 0));
  cv::imwrite("/tmp/synth_box.png", r.render(box, view(0.6, 45, 30), 0));
}

}  // namespace
}  // namespace v4r::synth
