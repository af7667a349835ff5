// v4r - robust model-based object tracking. MIT licence.
#include <random>

#include <gtest/gtest.h>

#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3_jacobians.hpp"

namespace v4r::geometry {
namespace {

TEST(NormalMotionJacobian, MatchesTheProjectedMoveOfASmallLeftUpdate) {
  const PinholeCamera K{640, 480, 600.0, 580.0, 320.0, 240.0};  // width height fx fy cx cy
  std::mt19937 g(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d Xc(0.2 * u(g), 0.15 * u(g), 0.8 + 0.5 * u(g));
    const Eigen::Vector2d n = Eigen::Vector2d(u(g), u(g)).normalized();
    const Vector6d J = normal_motion_jacobian(Xc, n, K.fx, K.fy);
    for (int i = 0; i < 6; ++i) {
      // Central differences of n . project(exp(+-h e_i) Xc).
      const double h = 1e-6;
      Vector6d d = Vector6d::Zero();
      d[i] = h;
      const double plus = n.dot(K.project(SE3::exp(d) * Xc)), minus = n.dot(K.project(SE3::exp(-d) * Xc));
      EXPECT_NEAR(J[i], (plus - minus) / (2.0 * h), 1e-4 * (1.0 + std::abs(J[i]))) << "trial " << trial << " component " << i;
    }
  }
}

TEST(NormalMotionJacobian, AMoveAlongTheEdgeIsInvisible) {
  // A point on the optical axis moved sideways along x: seen along n = (0, 1) it does not move.
  const Vector6d J = normal_motion_jacobian(Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector2d(0.0, 1.0), 500.0, 500.0);
  EXPECT_DOUBLE_EQ(J[0], 0.0);
  EXPECT_DOUBLE_EQ(J[1], 500.0);
}

}  // namespace
}  // namespace v4r::geometry
