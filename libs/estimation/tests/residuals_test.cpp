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

// ---------------------------------------------------------------------------------------------
// 3-D points, surface normals, circles.

namespace {

/// Central-difference Jacobian (M rows) of f(exp(delta) * T) at delta = 0.
template <int M, class F>
Eigen::Matrix<double, M, 6> numeric_jacobian_m(const SE3& T, F f, double h = 1e-6) {
  Eigen::Matrix<double, M, 6> J;
  for (int k = 0; k < 6; ++k) {
    Vector6d d = Vector6d::Zero();
    d[k] = h;
    J.col(k) = (f(SE3::exp(d) * T) - f(SE3::exp(-d) * T)) / (2.0 * h);
  }
  return J;
}

template <int M>
double rel_error_m(const Eigen::Matrix<double, M, 6>& a, const Eigen::Matrix<double, M, 6>& b) {
  return (a - b).norm() / std::max(1.0, b.norm());
}

/// \brief A circle in the object frame (centre, unit axis, radius) with an in-plane basis.
struct TestCircle {
  Eigen::Vector3d c, a, e1, e2;
  double radius;
  Eigen::Vector3d at(double phi) const { return c + radius * (std::cos(phi) * e1 + std::sin(phi) * e2); }
};

TestCircle random_circle(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> r(0.02, 0.1);
  TestCircle tc;
  tc.c = random_point(rng, 0.1);
  tc.a = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
  const DirectionBasis b = direction_basis(tc.a);
  tc.e1 = b.b1;
  tc.e2 = b.b2;
  tc.radius = r(rng);
  return tc;
}

/// A pose under which the circle's plane is seen at least `min_incidence` (|cos|) from the ray
/// to its centre, and the circle is well in front of the camera.
SE3 pose_seeing(std::mt19937& rng, const TestCircle& tc, double min_incidence) {
  for (;;) {
    const SE3 T = random_pose(rng);
    const Eigen::Vector3d c = T * tc.c, a = T.quaternion() * tc.a;
    if (c.z() > 0.3 && std::abs(a.dot(c.normalized())) > min_incidence) return T;
  }
}

Eigen::Vector2d normalised(const Eigen::Vector3d& p) { return {p.x() / p.z(), p.y() / p.z()}; }

}  // namespace

TEST(Residuals, DirectionBasisIsOrthonormal) {
  std::mt19937 rng(20);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3d v = k < 3 ? Eigen::Vector3d::Unit(k) * 2.0 : Eigen::Vector3d(n(rng), n(rng), n(rng));
    const DirectionBasis b = direction_basis(v);
    EXPECT_NEAR(b.n.norm(), 1.0, 1e-12);
    EXPECT_NEAR(b.b1.norm(), 1.0, 1e-12);
    EXPECT_NEAR(b.b2.norm(), 1.0, 1e-12);
    EXPECT_NEAR(b.b1.dot(b.n), 0.0, 1e-12);
    EXPECT_NEAR(b.b2.dot(b.n), 0.0, 1e-12);
    EXPECT_NEAR(b.b1.dot(b.b2), 0.0, 1e-12);
    EXPECT_LT((b.n - v.normalized()).norm(), 1e-12);
  }
}

TEST(Residuals, Point3JacobianMatchesCentralDifferences) {
  std::mt19937 rng(21);
  double worst = 0.0;
  for (int k = 0; k < 300; ++k) {
    const SE3 T = random_pose(rng);
    const Eigen::Vector3d X = random_point(rng, 0.3), P = T * X + random_point(rng, 0.01);
    Matrix36d J;
    const Eigen::Vector3d r = point3_residual(T, X, P, &J);
    EXPECT_LT((r - (T * X - P)).norm(), 1e-15);
    const Matrix36d Jn = numeric_jacobian_m<3>(T, [&](const SE3& Tp) { return point3_residual(Tp, X, P); });
    worst = std::max(worst, rel_error_m<3>(J, Jn));
  }
  EXPECT_LT(worst, 1e-6);
}

TEST(Residuals, NormalResidualAndJacobian) {
  std::mt19937 rng(22);
  std::normal_distribution<double> n(0.0, 1.0);
  double worst = 0.0;
  for (int k = 0; k < 300; ++k) {
    const SE3 T = random_pose(rng);
    const Eigen::Vector3d n_obj = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
    const Eigen::Vector3d m = T.quaternion() * n_obj;
    // The true normal gives zero; one tilted by a small angle alpha gives |r| = sin(alpha).
    EXPECT_LT(normal_residual(T, n_obj, direction_basis(m)).norm(), 1e-12);
    const double alpha = 0.05 * std::abs(n(rng));
    const Eigen::Vector3d axis = m.cross(Eigen::Vector3d(n(rng), n(rng), n(rng))).normalized();
    const Eigen::Vector3d n_cam = Eigen::AngleAxisd(alpha, axis) * m;
    const DirectionBasis b = direction_basis(n_cam);
    Matrix26d J;
    EXPECT_NEAR(normal_residual(T, n_obj, b, &J).norm(), std::sin(alpha), 1e-12);
    EXPECT_EQ(J.leftCols<3>().cwiseAbs().maxCoeff(), 0.0);  // rotation only
    const Matrix26d Jn = numeric_jacobian_m<2>(T, [&](const SE3& Tp) { return normal_residual(Tp, n_obj, b); });
    worst = std::max(worst, rel_error_m<2>(J, Jn));
    // A flipped prediction is reported unusable.
    Eigen::Vector2d rw;
    EXPECT_TRUE(normalised_normal_residual(m, b, 0.02, rw));
    EXPECT_FALSE(normalised_normal_residual(-m, b, 0.02, rw));
  }
  EXPECT_LT(worst, 1e-6);
}

TEST(Residuals, CircleResidualVanishesOnTheCircleAndMeasuresRadialOffset) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> ang(0.0, 6.283185307179586);
  for (int k = 0; k < 200; ++k) {
    const TestCircle tc = random_circle(rng);
    const SE3 T = pose_seeing(rng, tc, 0.2);
    const double phi = ang(rng);
    const CircleIntersection ci = circle_residual(T, tc.c, tc.a, tc.radius, normalised(T * tc.at(phi)));
    ASSERT_TRUE(ci.valid);
    EXPECT_NEAR(ci.residual, 0.0, 1e-12);
    EXPECT_NEAR(ci.depth, (T * tc.at(phi)).z(), 1e-9);
    // A point of the plane 5 mm outside the circle, seen through its own ray: r = +5 mm.
    const Eigen::Vector3d out = tc.c + (tc.radius + 0.005) * (tc.at(phi) - tc.c).normalized();
    EXPECT_NEAR(circle_residual(T, tc.c, tc.a, tc.radius, normalised(T * out)).residual, 0.005, 1e-12);
  }
  // Ray parallel to the plane, and the plane behind the camera: unusable.
  const Eigen::Vector3d c(0.0, 0.0, 1.0);
  EXPECT_FALSE(circle_residual_at(c, Eigen::Vector3d::UnitX(), 0.05, {0.0, 0.0}).valid);
  EXPECT_FALSE(circle_residual_at(-c, Eigen::Vector3d::UnitZ(), 0.05, {0.01, 0.0}).valid);
  EXPECT_TRUE(circle_residual_at(c, Eigen::Vector3d::UnitZ(), 0.05, {0.01, 0.0}).valid);
}

TEST(Residuals, CircleJacobianMatchesCentralDifferences) {
  std::mt19937 rng(24);
  std::uniform_real_distribution<double> ang(0.0, 6.283185307179586), off(-0.01, 0.01);
  double worst = 0.0;
  for (int k = 0; k < 300; ++k) {
    const TestCircle tc = random_circle(rng);
    const SE3 T = pose_seeing(rng, tc, 0.2);
    const Eigen::Vector2d xn = normalised(T * tc.at(ang(rng))) + Eigen::Vector2d(off(rng), off(rng));
    Matrix16d J;
    ASSERT_TRUE(circle_residual(T, tc.c, tc.a, tc.radius, xn, &J).valid);
    const Matrix16d Jn = numeric_jacobian_m<1>(T, [&](const SE3& Tp) {
      return Eigen::Matrix<double, 1, 1>(circle_residual(Tp, tc.c, tc.a, tc.radius, xn).residual);
    });
    worst = std::max(worst, rel_error_m<1>(J, Jn));
  }
  EXPECT_LT(worst, 1e-6);
}

// The circle weighting: d r / d xn (numeric, pose fixed) has norm depth * gain, so isotropic
// image noise sigma (normalised units) maps to sigma_r = depth * gain * sigma; and an edge point
// moved d pixels across the ellipse gives |rw| * sigma_px == d, at any obliqueness.
TEST(Residuals, CircleImageNoiseMapsToObjectSpaceSigma) {
  std::mt19937 rng(25);
  std::uniform_real_distribution<double> ang(0.0, 6.283185307179586);
  const double h = 1e-7, f = 600.0, sigma_px = 0.8, d_px = 1e-3;
  ResidualWeighting w;
  w.focal_px = f;
  double max_gain = 0.0;
  for (int k = 0; k < 200; ++k) {
    const TestCircle tc = random_circle(rng);
    const SE3 T = pose_seeing(rng, tc, 0.1);
    const Eigen::Vector3d c = T * tc.c, a = T.quaternion() * tc.a;
    const Eigen::Vector2d xn = normalised(T * tc.at(ang(rng)));
    const CircleIntersection ci = circle_residual_at(c, a, tc.radius, xn);
    ASSERT_TRUE(ci.valid);
    Eigen::Vector2d grad;
    for (int i = 0; i < 2; ++i) {
      Eigen::Vector2d d = Eigen::Vector2d::Zero();
      d[i] = h;
      grad[i] = (circle_residual_at(c, a, tc.radius, xn + d).residual -
                 circle_residual_at(c, a, tc.radius, xn - d).residual) / (2 * h);
    }
    EXPECT_NEAR(grad.norm() / (ci.depth * ci.gain), 1.0, 1e-5);
    max_gain = std::max(max_gain, ci.gain);
    // Move across the ellipse (along the gradient) by d_px pixels.
    double rw = 0.0;
    ASSERT_TRUE(normalised_circle_residual(c, a, tc.radius, xn + d_px / f * grad.normalized(), sigma_px, w, rw));
    EXPECT_NEAR(std::abs(rw) * sigma_px / d_px, 1.0, 2e-3);
    // Along the ellipse: no first-order change.
    const Eigen::Vector2d along(-grad.y(), grad.x());
    ASSERT_TRUE(normalised_circle_residual(c, a, tc.radius, xn + d_px / f * along.normalized(), sigma_px, w, rw));
    EXPECT_LT(std::abs(rw) * sigma_px / d_px, 2e-3);
  }
  EXPECT_GT(max_gain, 2.0);  // oblique views were covered
}

// 3-D points: constant weights, the normalised Jacobian is the analytic one over sigma. Circles:
// the weight depends on the pose and is differentiated too; compare with central differences
// of the normalised residual, also without the oblique factor and with the depth clamped.
TEST(Residuals, NewNormalisedJacobiansMatchCentralDifferences) {
  std::mt19937 rng(26);
  std::uniform_real_distribution<double> ang(0.0, 6.283185307179586);
  double worst = 0.0;
  for (int k = 0; k < 150; ++k) {
    ResidualWeighting w;
    w.focal_px = 600.0;
    w.oblique = k % 3 != 1;
    if (k % 3 == 2) w.min_depth = 10.0;  // clamped: constant depth factor
    const TestCircle tc = random_circle(rng);
    const SE3 T = pose_seeing(rng, tc, 0.2);
    const Eigen::Vector2d xn = normalised(T * tc.at(ang(rng))) + Eigen::Vector2d(0.01, -0.008);
    const auto rw_at = [&](const SE3& Tp) {
      double r = 0.0;
      EXPECT_TRUE(normalised_circle_residual(Tp * tc.c, Tp.quaternion() * tc.a, tc.radius, xn, 0.5, w, r));
      return Eigen::Matrix<double, 1, 1>(r);
    };
    Matrix16d J, Jw;
    const CircleIntersection ci = circle_residual(T, tc.c, tc.a, tc.radius, xn, &J);
    double rw = 0.0;
    ASSERT_TRUE(normalised_circle_residual(T * tc.c, T.quaternion() * tc.a, tc.radius, xn, 0.5, w, rw, &Jw));
    const double gain = w.oblique ? ci.gain : 1.0;
    EXPECT_NEAR(rw, ci.residual * 600.0 / (0.5 * std::max(ci.depth, w.min_depth) * gain), 1e-9 * std::abs(rw));
    const Matrix16d Jn = numeric_jacobian_m<1>(T, rw_at);
    worst = std::max(worst, (Jw - Jn).norm() / std::max(1.0, Jn.norm()));

    const Eigen::Vector3d X = random_point(rng, 0.2), P = T * X + random_point(rng, 0.01);
    Eigen::Vector3d r3;
    Matrix36d J3, J3w;
    point3_residual(T, X, P, &J3);
    normalised_point3_residual(T * X, P, 0.002, r3, &J3w);
    EXPECT_LT((J3w - J3 / 0.002).norm(), 1e-9 * J3w.norm());
    EXPECT_LT((r3 - (T * X - P) / 0.002).norm(), 1e-9 * r3.norm());
  }
  EXPECT_LT(worst, 1e-6);
}
