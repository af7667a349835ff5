// v4r - robust model-based object tracking. MIT licence.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "v4r/estimation/residuals.hpp"
#include "v4r/geometry/se3.hpp"

using namespace v4r::estimation;
using v4r::geometry::SE3;
using v4r::geometry::Vector6d;

namespace {

Vector6d random_twist(std::mt19937& rng, double t_scale, double r_scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vector6d xi;
  for (int i = 0; i < 3; ++i) xi[i] = t_scale * u(rng);
  for (int i = 3; i < 6; ++i) xi[i] = r_scale * u(rng);
  return xi;
}

/// A random pose that puts the object origin 0.3 - 1.5 m in front of the camera.
SE3 random_pose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d t(0.2 * u(rng), 0.2 * u(rng), 0.9 + 0.6 * u(rng));
  const Eigen::Vector3d w(u(rng), u(rng), u(rng));
  return SE3::from_rvec(t, 3.0 * w.normalized() * std::abs(u(rng)));
}

Eigen::Vector3d random_point(std::mt19937& rng, double half) {
  std::uniform_real_distribution<double> u(-half, half);
  return {u(rng), u(rng), u(rng)};
}

/// Central-difference Jacobian of f(exp(delta) * T) at delta = 0.
template <class F>
Matrix26d numeric_jacobian(const SE3& T, F f, double h = 1e-6) {
  Matrix26d J;
  for (int k = 0; k < 6; ++k) {
    Vector6d d = Vector6d::Zero();
    d[k] = h;
    const Eigen::Vector2d rp = f(SE3::exp(d) * T);
    const Eigen::Vector2d rm = f(SE3::exp(-d) * T);
    J.col(k) = (rp - rm) / (2.0 * h);
  }
  return J;
}

double rel_error(const Matrix26d& a, const Matrix26d& b) { return (a - b).norm() / std::max(1.0, b.norm()); }

}  // namespace

TEST(Residuals, RayBasisIsOrthonormalAndPerpendicular) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.8, 0.8);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector2d xn = k == 0 ? Eigen::Vector2d::Zero() : Eigen::Vector2d(u(rng), u(rng));
    const RayBasis b = ray_basis(xn);
    EXPECT_NEAR(b.e1.norm(), 1.0, 1e-12);
    EXPECT_NEAR(b.e2.norm(), 1.0, 1e-12);
    EXPECT_NEAR(b.e1.dot(b.e2), 0.0, 1e-12);
    EXPECT_NEAR(b.e1.dot(b.u), 0.0, 1e-12);
    EXPECT_NEAR(b.e2.dot(b.u), 0.0, 1e-12);
    EXPECT_NEAR(b.e1.z(), 0.0, 1e-12);
    EXPECT_NEAR(b.cos_theta, 1.0 / std::sqrt(1.0 + xn.squaredNorm()), 1e-12);
  }
}

TEST(Residuals, PointResidualIsDistanceFromLineOfSight) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  for (int k = 0; k < 100; ++k) {
    const Eigen::Vector2d xn(u(rng), u(rng));
    const RayBasis b = ray_basis(xn);
    const double depth = 0.5 + std::abs(u(rng));
    const Eigen::Vector3d on_ray = depth * Eigen::Vector3d(xn.x(), xn.y(), 1.0);
    EXPECT_LT(point_residual_at(on_ray, b).norm(), 1e-12);
    const Eigen::Vector3d off = on_ray + random_point(rng, 0.05);
    const Eigen::Vector3d along = off.dot(b.u) * b.u;
    EXPECT_NEAR(point_residual_at(off, b).norm(), (off - along).norm(), 1e-12);
  }
}

TEST(Residuals, InterpretationPlaneContainsTheImageLine) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  for (int k = 0; k < 100; ++k) {
    const Eigen::Vector2d a(u(rng), u(rng)), b(u(rng), u(rng));
    const Eigen::Vector3d n = interpretation_plane_normal(a, b);
    EXPECT_NEAR(n.norm(), 1.0, 1e-12);
    // Any point on the viewing ray of any point of the image line lies in the plane.
    const double s = u(rng), depth = 1.0 + u(rng);
    const Eigen::Vector2d m = a + s * (b - a);
    EXPECT_NEAR(plane_residual_at(depth * Eigen::Vector3d(m.x(), m.y(), 1.0), n), 0.0, 1e-12);
  }
  EXPECT_EQ(interpretation_plane_normal({0.1, 0.2}, {0.1, 0.2}), Eigen::Vector3d::Zero());
}

TEST(Residuals, PointJacobianMatchesCentralDifferences) {
  std::mt19937 rng(14);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  double worst = 0.0;
  for (int k = 0; k < 300; ++k) {
    const SE3 T = random_pose(rng);
    const Eigen::Vector3d X = random_point(rng, 0.3);
    const RayBasis b = ray_basis(Eigen::Vector2d(u(rng), u(rng)));
    Matrix26d J;
    point_residual(T, X, b, &J);
    const Matrix26d Jn = numeric_jacobian(T, [&](const SE3& Tp) { return point_residual(Tp, X, b); });
    worst = std::max(worst, rel_error(J, Jn));
  }
  EXPECT_LT(worst, 1e-6);
}

TEST(Residuals, LineJacobianMatchesCentralDifferences) {
  std::mt19937 rng(15);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  double worst = 0.0;
  for (int k = 0; k < 300; ++k) {
    const SE3 T = random_pose(rng);
    const Eigen::Vector3d X1 = random_point(rng, 0.3), X2 = random_point(rng, 0.3);
    const Eigen::Vector3d n = interpretation_plane_normal({u(rng), u(rng)}, {u(rng), u(rng)});
    Matrix26d J;
    line_residual(T, X1, X2, n, &J);
    const Matrix26d Jn = numeric_jacobian(T, [&](const SE3& Tp) { return line_residual(Tp, X1, X2, n); });
    worst = std::max(worst, rel_error(J, Jn));
  }
  EXPECT_LT(worst, 1e-6);
}

TEST(Residuals, JacobiansAtLargerPerturbationsStayConsistent) {
  // Linearisation check: r(exp(d) T) - r(T) - J d is O(|d|^2).
  std::mt19937 rng(16);
  for (int k = 0; k < 50; ++k) {
    const SE3 T = random_pose(rng);
    const Eigen::Vector3d X = random_point(rng, 0.3);
    const RayBasis b = ray_basis(Eigen::Vector2d(0.2, -0.1));
    Matrix26d J;
    const Eigen::Vector2d r0 = point_residual(T, X, b, &J);
    const Vector6d d = random_twist(rng, 1.0, 1.0);
    const double e1 = (point_residual(SE3::exp(1e-3 * d) * T, X, b) - r0 - J * (1e-3 * d)).norm();
    const double e2 = (point_residual(SE3::exp(2e-3 * d) * T, X, b) - r0 - J * (2e-3 * d)).norm();
    EXPECT_NEAR(e2 / std::max(e1, 1e-15), 4.0, 0.2);  // second-order remainder
  }
}

// The weighting model of the solver: an image displacement d (normalised units) of a point at
// depth z changes the point discrepancy by z * (e1 . d, cos(theta) * e2' . d), i.e. isotropic
// image noise maps to object-space sigmas z * sigma * (1, cos(theta)); a line moved across by
// d changes the plane distance of a point at depth z by z * d * sqrt(1 - n_z^2).
TEST(Residuals, ImageNoiseMapsToObjectSpaceSigmas) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-0.6, 0.6);
  const double h = 1e-7;
  for (int k = 0; k < 100; ++k) {
    const Eigen::Vector2d xn(u(rng), u(rng));
    const double z = 0.4 + std::abs(u(rng));
    const Eigen::Vector3d p = z * Eigen::Vector3d(xn.x(), xn.y(), 1.0);
    const RayBasis b = ray_basis(xn);
    Eigen::Matrix2d Jx;  // d r / d xn at fixed p
    for (int c = 0; c < 2; ++c) {
      Eigen::Vector2d d = Eigen::Vector2d::Zero();
      d[c] = h;
      Jx.col(c) = (point_residual_at(p, ray_basis(xn + d)) - point_residual_at(p, ray_basis(xn - d))) / (2 * h);
    }
    const Eigen::Matrix2d cov = Jx * Jx.transpose();  // covariance per unit isotropic image noise
    EXPECT_NEAR(cov(0, 0) / (z * z), 1.0, 1e-6);
    EXPECT_NEAR(cov(1, 1) / (z * z * b.cos_theta * b.cos_theta), 1.0, 1e-6);
    EXPECT_NEAR(cov(0, 1) / (z * z), 0.0, 1e-6);

    // Line through p: shift it across (perpendicular in the image) by h.
    const Eigen::Vector2d dir = Eigen::Vector2d(u(rng), u(rng)).normalized();
    const Eigen::Vector2d across(-dir.y(), dir.x());
    const Eigen::Vector2d a = xn - 0.1 * dir, c = xn + 0.2 * dir;
    const Eigen::Vector3d n = interpretation_plane_normal(a, c);
    const double rp = plane_residual_at(p, interpretation_plane_normal(a + h * across, c + h * across));
    const double rm = plane_residual_at(p, interpretation_plane_normal(a - h * across, c - h * across));
    EXPECT_NEAR(std::abs(rp - rm) / (2 * h), z * std::sqrt(1.0 - n.z() * n.z()), 1e-6 * z);
  }
}

// Normalised residuals are image displacements in units of sigma: an observation d pixels away
// from the projection gives |rw| * sigma_px == |d|, at any depth and off-axis angle, in any
// direction. This pins down the weights (depth, cos(theta), sqrt(1 - n_z^2), focal length).
TEST(Residuals, NormalisedResidualsArePixelDisplacementsInSigmas) {
  std::mt19937 rng(18);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double f = 600.0, sigma_px = 0.7, d_px = 0.01;
  ResidualWeighting w;
  w.focal_px = f;
  for (int k = 0; k < 200; ++k) {
    // Points up to 35 degrees off axis, 0.3 - 3 m deep.
    const Eigen::Vector3d p = (0.3 + 1.35 * (1.0 + u(rng))) * Eigen::Vector3d(0.7 * u(rng), 0.7 * u(rng), 1.0);
    const Eigen::Vector2d xp(p.x() / p.z(), p.y() / p.z());
    const double a = 3.14159265 * u(rng);
    const Eigen::Vector2d shift = d_px / f * Eigen::Vector2d(std::cos(a), std::sin(a));
    Eigen::Vector2d rw;
    normalised_point_residual(p, ray_basis(xp + shift), sigma_px, w, rw);
    EXPECT_NEAR(rw.norm() * sigma_px / d_px, 1.0, 2e-3) << "depth " << p.z() << " xn " << xp.transpose();

    // Edge p, q; the observed image line passes d1 / d2 pixels beside their projections.
    const Eigen::Vector3d q = p + 0.2 * Eigen::Vector3d(u(rng), u(rng), 0.5 * u(rng));
    const Eigen::Vector2d xq(q.x() / q.z(), q.y() / q.z());
    const Eigen::Vector2d dir = (xq - xp).normalized(), across(-dir.y(), dir.x());
    const double d1 = d_px * u(rng), d2 = d_px * u(rng);
    const Eigen::Vector3d n = interpretation_plane_normal(xp + d1 / f * across, xq + d2 / f * across);
    normalised_line_residual(p, q, n, sigma_px, w, rw);
    EXPECT_NEAR(std::abs(rw.x()) * sigma_px, std::abs(d1), 2e-3 * d_px);
    EXPECT_NEAR(std::abs(rw.y()) * sigma_px, std::abs(d2), 2e-3 * d_px);
  }
}

// The solver freezes the weights within an iteration (Gauss-Newton): the normalised Jacobian is
// the analytic one with each row divided by the same sigma as its residual.
TEST(Residuals, NormalisedJacobiansAreRowScaledAnalyticJacobians) {
  std::mt19937 rng(19);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  ResidualWeighting w;
  w.focal_px = 600.0;
  for (int k = 0; k < 50; ++k) {
    const SE3 T = random_pose(rng);
    const Eigen::Vector3d X = random_point(rng, 0.2), Y = random_point(rng, 0.2);
    const RayBasis b = ray_basis(Eigen::Vector2d(u(rng), u(rng)));
    const Eigen::Vector3d n = interpretation_plane_normal({u(rng), u(rng)}, {u(rng), u(rng)});
    Eigen::Vector2d rw;
    Matrix26d Jw, J;
    normalised_point_residual(T * X, b, 0.5, w, rw, &Jw);
    Eigen::Vector2d r = point_residual(T, X, b, &J);
    Eigen::Matrix2d S = (rw.array() / r.array()).matrix().asDiagonal();
    EXPECT_LT((Jw - S * J).norm(), 1e-9 * Jw.norm());
    normalised_line_residual(T * X, T * Y, n, 0.5, w, rw, &Jw);
    r = line_residual(T, X, Y, n, &J);
    S = (rw.array() / r.array()).matrix().asDiagonal();
    EXPECT_LT((Jw - S * J).norm(), 1e-9 * Jw.norm());
  }
}
