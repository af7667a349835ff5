// v4r - robust model-based object tracking. MIT licence.
// GrazingFaces: the poses that turn a face seen edge-on into view.
#include <array>
#include <cmath>

#include <gtest/gtest.h>

#include "degrees.hpp"
#include "v4r/detection/grazing_faces.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/synth/renderer.hpp"

using namespace v4r;
using namespace v4r::detection;

namespace {

model::Model box() {
  auto m = model::parse_cao(synth::box_cao(), "box");
  EXPECT_TRUE(m);
  return std::move(*m);
}

/// Elevation of the line of sight above the box's +x face (centroid (0.1, 0, 0)): > 0 seen.
double seen_x_face(const geometry::SE3& T) {
  const Eigen::Vector3d n = T.rotation() * Eigen::Vector3d::UnitX();
  const Eigen::Vector3d to_camera = -(T * Eigen::Vector3d(0.1, 0.0, 0.0)).normalized();
  return std::asin(n.dot(to_camera));
}

/// The box 0.6 m ahead, seen along -y (its -y face towards the camera, z up), then turned about
/// its vertical axis so that the +x face is seen at `seen` (negative: turned away).
geometry::SE3 pose_seeing_x_face_at(double seen) {
  // Camera axes: x right, y down, z forward. Object -y faces the camera: object y -> camera z,
  // object z -> camera -y, object x -> camera x.
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  geometry::SE3 T(R, Eigen::Vector3d(0.0, 0.0, 0.6));
  // Bisect the turn about the object's z axis that gives the wanted elevation.
  const auto turned = [&](double a) {
    return geometry::SE3(Eigen::Matrix3d(R * Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix()), T.translation());
  };
  double lo = -1.0, hi = 1.0;
  const bool below_at_lo = seen_x_face(turned(lo)) < seen;
  for (int i = 0; i < 60; ++i) {
    const double a = 0.5 * (lo + hi);
    ((seen_x_face(turned(a)) < seen) == below_at_lo ? lo : hi) = a;
  }
  return geometry::SE3(Eigen::Matrix3d(R * Eigen::AngleAxisd(0.5 * (lo + hi), Eigen::Vector3d::UnitZ()).toRotationMatrix()),
                       T.translation());
}

}  // namespace

TEST(GrazingFaces, KeepsTheLargeFacesOfAModel) {
  const model::Model m = box();
  EXPECT_EQ(GrazingFaces(m).size(), 6u);
  // Its 0.20 x 0.10 m faces are two thirds of the largest (0.20 x 0.15 m), its 0.15 x 0.10 m
  // faces half of it.
  EXPECT_EQ(GrazingFaces(m, 0.6).size(), 4u);
  EXPECT_EQ(GrazingFaces(m, 0.7).size(), 2u);
}

TEST(GrazingFaces, AFaceTurnedJustAwayIsTurnedIntoViewAboutThePivot) {
  const model::Model m = box();
  const GrazingFaces g(m);
  const geometry::SE3 T = pose_seeing_x_face_at(-3.0 * kDeg);
  ASSERT_NEAR(seen_x_face(T), -3.0 * kDeg, 1e-6);
  const Eigen::Vector3d pivot(0.0, -0.075, 0.0);  // the centre of the face towards the camera
  std::array<geometry::SE3, 8> out;
  const std::size_t n = g.unfold(T, pivot, 15.0 * kDeg, 6.0 * kDeg, out);
  // Among the turned poses (the top and bottom faces, seen edge-on from the box's mid-height,
  // are turned too), one sees the +x face at 6 degrees (to 0.01); every turn keeps the pivot in
  // place.
  ASSERT_GE(n, 1u);
  int x_face_unfolded = 0;
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_LT((out[i] * pivot - T * pivot).norm(), 1e-9) << "the pivot stays in place";
    if (std::abs(seen_x_face(out[i]) - 6.0 * kDeg) < 0.01 * kDeg) ++x_face_unfolded;
  }
  EXPECT_EQ(x_face_unfolded, 1);
  // Only as many poses as asked for.
  EXPECT_EQ(g.unfold(T, pivot, 15.0 * kDeg, 6.0 * kDeg, std::span<geometry::SE3>(out).first(1)), 1u);
}

TEST(GrazingFaces, AFaceSeenWellOrTurnedFarAwayIsLeftAlone) {
  const model::Model m = box();
  const GrazingFaces g(m);
  std::array<geometry::SE3, 8> out;
  for (const double seen_deg : {20.0, -30.0}) {
    const geometry::SE3 T = pose_seeing_x_face_at(seen_deg * kDeg);
    ASSERT_NEAR(seen_x_face(T), seen_deg * kDeg, 1e-6);
    const std::size_t n = g.unfold(T, Eigen::Vector3d::Zero(), 15.0 * kDeg, 6.0 * kDeg, out);
    // Other faces may be turned; none of the poses turns the +x face to 6 degrees.
    for (std::size_t i = 0; i < n; ++i) EXPECT_GT(std::abs(seen_x_face(out[i]) - 6.0 * kDeg), 1e-3) << seen_deg;
  }
}
