// v4r - robust model-based object tracking. MIT licence.
// Test support shared by the pose solver tests: the synthetic camera (f = 600 px, principal point
// (319.5, 239.5)), projection to pixels and back, random perturbations of a pose and pose errors.
#pragma once

#include <random>

#include <Eigen/Core>

#include "v4r/estimation/pose_solver.hpp"
#include "v4r/geometry/se3.hpp"

namespace v4r::estimation::test {

constexpr double kF = 600.0, kCx = 319.5, kCy = 239.5;
constexpr double kPi = 3.14159265358979323846;

inline Eigen::Vector2d project_px(const geometry::SE3& T, const Eigen::Vector3d& X) {
  const Eigen::Vector3d p = T * X;
  return {kF * p.x() / p.z() + kCx, kF * p.y() / p.z() + kCy};
}
inline Eigen::Vector2d px_to_normalised(const Eigen::Vector2d& u) { return {(u.x() - kCx) / kF, (u.y() - kCy) / kF}; }

inline Eigen::Vector3d random_unit(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
}

/// Truth moved by `t_m` metres and `r_deg` degrees in random directions.
inline geometry::SE3 perturb(std::mt19937& rng, const geometry::SE3& T, double t_m, double r_deg) {
  geometry::Vector6d d;
  d.head<3>() = random_unit(rng) * t_m;
  d.tail<3>() = random_unit(rng) * (r_deg * kPi / 180.0);
  return geometry::SE3::exp(d) * T;
}

inline double t_error(const geometry::SE3& a, const geometry::SE3& b) {
  return (a.translation() - b.translation()).norm();
}
inline double r_error_deg(const geometry::SE3& a, const geometry::SE3& b) {
  return geometry::rotation_angle_between(a, b) * 180.0 / kPi;
}

inline PoseSolverParams params_600() {
  PoseSolverParams p;
  p.focal_px = kF;
  return p;
}

}  // namespace v4r::estimation::test
