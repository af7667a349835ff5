// v4r - robust model-based object tracking. MIT licence.
// The pinhole camera's lens model: the derivative of its distortion.
#include <random>

#include <gtest/gtest.h>

#include "v4r/geometry/camera.hpp"

namespace v4r::geometry {
namespace {

TEST(DistortJacobian, MatchesCentralDifferencesOfTheDistortion) {
  PinholeCamera K{640, 480, 600.0, 580.0, 320.0, 240.0};
  K.dist = {-0.28, 0.07, 0.0012, -0.0009, 0.02};  // strong radial, tangential terms, k3
  std::mt19937 g(11);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  constexpr double h = 1e-6;
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector2d q(u(g), u(g));
    const Eigen::Matrix2d J = K.distort_jacobian(q);
    for (int c = 0; c < 2; ++c) {
      const Eigen::Vector2d e = Eigen::Vector2d::Unit(c) * h;
      const Eigen::Vector2d fd = (K.distort(q + e) - K.distort(q - e)) / (2.0 * h);
      EXPECT_NEAR(J(0, c), fd.x(), 1e-7) << "trial " << trial << " column " << c;
      EXPECT_NEAR(J(1, c), fd.y(), 1e-7) << "trial " << trial << " column " << c;
    }
  }
  // Without distortion it is the identity.
  K.dist = {0, 0, 0, 0, 0};
  EXPECT_TRUE(K.distort_jacobian(Eigen::Vector2d(0.3, -0.2)).isIdentity(0.0));
}

}  // namespace
}  // namespace v4r::geometry
