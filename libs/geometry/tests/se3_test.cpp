// v4r - robust model-based object tracking. MIT licence.
#include <random>

#include <gtest/gtest.h>

#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"

using namespace v4r::geometry;

namespace {
Vector6d random_twist(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Vector6d xi;
  for (int i = 0; i < 6; ++i) xi[i] = u(rng);
  return xi;
}
}  // namespace

TEST(SE3, ExpLogRoundTrip) {
  std::mt19937 rng(3);
  for (int k = 0; k < 200; ++k) {
    const Vector6d xi = random_twist(rng, k < 20 ? 1e-7 : 1.5);
    const Vector6d back = SE3::exp(xi).log();
    EXPECT_LT((xi - back).norm(), 1e-9) << xi.transpose();
  }
}

TEST(SE3, ComposeInverseAndAct) {
  std::mt19937 rng(4);
  for (int k = 0; k < 50; ++k) {
    const SE3 a = SE3::exp(random_twist(rng, 2.0));
    const SE3 b = SE3::exp(random_twist(rng, 2.0));
    const Eigen::Vector3d p(0.1 * k, -0.2, 0.3);
    EXPECT_LT(((a * b) * p - a * (b * p)).norm(), 1e-12);
    EXPECT_LT(((a * a.inverse()) * p - p).norm(), 1e-12);
    EXPECT_LT((a.matrix() * p.homogeneous() - (a * p).homogeneous()).norm(), 1e-12);
  }
}

TEST(SE3, RvecMatchesRodrigues) {
  // 90 degrees about z maps x to y.
  const SE3 T = SE3::from_rvec(Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(0, 0, M_PI / 2));
  EXPECT_LT((T * Eigen::Vector3d(1, 0, 0) - Eigen::Vector3d(1, 3, 3)).norm(), 1e-12);
  EXPECT_LT((T.rvec() - Eigen::Vector3d(0, 0, M_PI / 2)).norm(), 1e-12);
}

TEST(SE3, LeftPerturbationJacobianMatchesNumeric) {
  // d/d(delta) of exp(delta) * T * p at delta = 0 equals [I, -hat(T p)].
  std::mt19937 rng(5);
  const SE3 T = SE3::exp(random_twist(rng, 1.0));
  const Eigen::Vector3d p(0.3, -0.1, 0.7);
  const Eigen::Vector3d q = T * p;
  Eigen::Matrix<double, 3, 6> J_analytic;
  J_analytic.leftCols<3>().setIdentity();
  J_analytic.rightCols<3>() = -hat(q);
  Eigen::Matrix<double, 3, 6> J_num;
  const double h = 1e-6;
  for (int i = 0; i < 6; ++i) {
    Vector6d d = Vector6d::Zero();
    d[i] = h;
    J_num.col(i) = ((SE3::exp(d) * T) * p - (SE3::exp(-d) * T) * p) / (2 * h);
  }
  EXPECT_LT((J_analytic - J_num).norm(), 1e-7);
}

TEST(PinholeCamera, DistortUndistortRoundTrip) {
  PinholeCamera cam;
  cam.width = 640;
  cam.height = 480;
  cam.fx = 600;
  cam.fy = 602;
  cam.cx = 319.5;
  cam.cy = 239.5;
  cam.dist = {-0.12, 0.05, 0.001, -0.0005, 0.0};
  for (double x = -0.5; x <= 0.5; x += 0.1) {
    for (double y = -0.4; y <= 0.4; y += 0.1) {
      const Eigen::Vector2d xn(x, y);
      const Eigen::Vector2d px = cam.normalized_to_pixel(xn);
      EXPECT_LT((cam.pixel_to_normalized(px) - xn).norm(), 1e-9);
    }
  }
  EXPECT_LT((cam.project(Eigen::Vector3d(0, 0, 1)) - Eigen::Vector2d(319.5, 239.5)).norm(), 1e-12);
}
