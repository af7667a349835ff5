// v4r - robust model-based object tracking. MIT licence.
// The renderer draws model points where OpenCV's camera model puts them: checked against
// cv::projectPoints (k1 k2 p1 p2 k3), independently of v4r's own PinholeCamera::project.
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "v4r/model/model.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::synth {
namespace {

using geometry::PinholeCamera;
using geometry::SE3;

/// A 0.6 x 0.3 m rectangle in the object's z = 0 plane, normal +z, whose edge on the x axis
/// (y = 0, x in [-0.3, 0.3]) is the one the test looks at; the face covers y >= 0.
model::Model half_plane() {
  model::ModelBuilder b("half_plane");
  const model::Index a = b.add_junction({-0.3, 0.0, 0.0}), c = b.add_junction({0.3, 0.0, 0.0}),
                     d = b.add_junction({0.3, 0.3, 0.0}), e = b.add_junction({-0.3, 0.3, 0.0});
  EXPECT_TRUE(b.add_face({a, c, d, e}));
  return std::move(b).build().value();
}

/// cv::projectPoints of camera-frame points with the camera's K and (k1 k2 p1 p2 k3).
std::vector<cv::Point2d> opencv_project(const PinholeCamera& cam, const std::vector<cv::Point3d>& p_cam) {
  const cv::Matx33d K(cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1);
  const std::vector<double> dist(cam.dist.begin(), cam.dist.end());
  std::vector<cv::Point2d> px;
  cv::projectPoints(p_cam, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, dist, px);
  return px;
}

/// Distance (pixels) from `q` to the polyline through `pts`.
double distance_to_polyline(const std::vector<cv::Point2d>& pts, const cv::Point2d& q) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
    const cv::Point2d ab = pts[i + 1] - pts[i], aq = q - pts[i];
    const double t = std::clamp(aq.dot(ab) / std::max(ab.dot(ab), 1e-30), 0.0, 1.0);
    best = std::min(best, cv::norm(aq - t * ab));
  }
  return best;
}

/// For pixel (x0, y0): places the face's edge near the pixel centre (edge direction `theta` in
/// the face plane, face tilted by `tilt`), slides the face across the pixel centre along its
/// plane until the renderer's object mask at that pixel flips (bisection), and returns the
/// distance in pixels between the pixel centre and cv::projectPoints' image of the edge at that
/// pose. The renderer's mask is decided by the ray through the pixel centre, so a renderer that
/// projects like OpenCV gives ~0.
double edge_offset_px(const Renderer& r, const model::Model& m, int x0, int y0, double theta, double tilt) {
  const PinholeCamera& cam = r.camera();
  // Ray through the pixel centre, from OpenCV's inverse model (only to place the face nearby).
  const cv::Matx33d K(cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1);
  const std::vector<double> dist(cam.dist.begin(), cam.dist.end());
  std::vector<cv::Point2d> xn;
  cv::undistortPoints(std::vector<cv::Point2d>{{double(x0), double(y0)}}, xn, K, dist);
  const double depth = 0.5;
  const Eigen::Vector3d t0(xn[0].x * depth, xn[0].y * depth, depth);
  // Object z towards the camera (rotation by pi about x), edge turned by theta, plane tilted.
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(tilt, Eigen::Vector3d(1, 1, 0).normalized()) *
                             Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()))
                                .toRotationMatrix();
  const Eigen::Vector3d ex = R.col(0), ey = R.col(1);
  auto pose = [&](double s) { return SE3(R, t0 + s * ey); };
  auto inside = [&](double s) {
    FrameInfo info;
    r.render(m, pose(s), 0, nullptr, &info);
    return info.object_mask.at<std::uint8_t>(y0, x0) != 0;
  };
  double lo = -0.004, hi = 0.004;  // metres: about +-5 px at 0.5 m
  const bool in_lo = inside(lo);
  EXPECT_NE(in_lo, inside(hi)) << "the edge does not cross pixel (" << x0 << ", " << y0 << ")";
  for (int it = 0; it < 16; ++it) {  // 8 mm / 2^16: 1.2e-7 m, ~1.5e-4 px at 0.5 m
    const double mid = 0.5 * (lo + hi);
    (inside(mid) == in_lo ? lo : hi) = mid;
  }
  const Eigen::Vector3d origin = t0 + 0.5 * (lo + hi) * ey;
  std::vector<cv::Point3d> edge;
  for (double l = -0.02; l <= 0.02; l += 2e-5) {  // +-24 px of the edge, 0.024 px steps
    const Eigen::Vector3d p = origin + l * ex;
    edge.emplace_back(p.x(), p.y(), p.z());
  }
  return distance_to_polyline(opencv_project(cam, edge), cv::Point2d(x0, y0));
}

void check_camera(const PinholeCamera& cam, const char* name) {
  RenderOptions opt;
  opt.noise_sigma = 0.0;
  opt.colour = false;
  opt.supersample = 1;  // the mask is decided at pixel centres anyway
  opt.textured_background = false;
  const Renderer r(cam, opt);
  const model::Model m = half_plane();
  // The centre, near the four corners (strongest distortion), mid-edges and in between.
  const std::vector<cv::Point> pixels{{320, 240}, {12, 10}, {627, 9},   {8, 470},   {630, 468},
                                      {320, 6},   {5, 241}, {633, 250}, {160, 120}, {480, 370}};
  double worst = 0.0;
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const double theta = 0.41 * static_cast<double>(i);              // edge directions all round
    const double tilt = (i % 2 ? 1.0 : -1.0) * 0.35;                 // face plane not fronto-parallel
    const double d = edge_offset_px(r, m, pixels[i].x, pixels[i].y, theta, tilt);
    EXPECT_LT(d, 0.01) << name << ": pixel (" << pixels[i].x << ", " << pixels[i].y << ")";
    worst = std::max(worst, d);
  }
  std::printf("[%s] renderer vs cv::projectPoints: largest offset %.2e px over %zu pixels\n", name, worst,
              pixels.size());
  ::testing::Test::RecordProperty(std::string(name) + "_max_offset_px", std::to_string(worst));
}

TEST(RendererProjection, AgreesWithOpenCvProjectPointsWithTheDefaultCamera) {
  check_camera(default_camera(), "default camera");
}

TEST(RendererProjection, AgreesWithOpenCvProjectPointsWithStrongFullDistortion) {
  PinholeCamera cam;
  cam.width = 640;
  cam.height = 480;
  cam.fx = 610.0;
  cam.fy = 604.0;
  cam.cx = 318.7;
  cam.cy = 243.2;
  cam.dist = {-0.28, 0.09, 0.0012, -0.0009, -0.015};  // k1 k2 p1 p2 k3: a wide-angle lens
  check_camera(cam, "strong distortion");
}

}  // namespace
}  // namespace v4r::synth
