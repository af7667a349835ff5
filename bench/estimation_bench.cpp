// v4r - robust model-based object tracking. MIT licence.
//
// Micro benchmarks of the object-space pose solver (estimation::PoseSolver::solve): a typical
// tracking frame of 20 edges + 8 points, clean and with 5 gross outliers, from a start pose 2 cm
// and 5 degrees off; the same frame with two circles (2 x 12 edge points), 6 stereo points and 3
// surface normals added; and one time / measurement update of the SE(3) pose filter.
#include <cmath>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "v4r/estimation/pose_solver.hpp"
#include "v4r/filter/pose_filter.hpp"

namespace {

using v4r::estimation::CircleObservation;
using v4r::estimation::LineObservation;
using v4r::estimation::NormalObservation;
using v4r::estimation::ObservationSet;
using v4r::estimation::Point3Observation;
using v4r::estimation::PointObservation;
using v4r::estimation::PoseResult;
using v4r::estimation::PoseSolver;
using v4r::estimation::PoseSolverParams;
using v4r::geometry::SE3;
using v4r::geometry::Vector6d;

constexpr double kF = 600.0, kCx = 319.5, kCy = 239.5;

/// \brief One synthetic frame: observations of a 0.3 m object ~0.6 m in front of a 640x480 camera.
struct Frame {
  SE3 T_init;
  std::vector<PointObservation> points;
  std::vector<LineObservation> lines;
  std::vector<CircleObservation> circles;
  std::vector<Point3Observation> points3d;
  std::vector<NormalObservation> normals;
};

Frame make_frame(int n_points, int n_lines, int n_outliers, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> cube(-0.15, 0.15), gross(15.0, 60.0), unit(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.5);
  const SE3 T = SE3::from_rvec({0.02, -0.01, 0.6}, {0.4, -0.3, 0.2});
  const auto px = [&](const Eigen::Vector3d& X) {
    const Eigen::Vector3d p = T * X;
    return Eigen::Vector2d(kF * p.x() / p.z() + kCx, kF * p.y() / p.z() + kCy);
  };
  const auto norm = [](const Eigen::Vector2d& u) { return Eigen::Vector2d((u.x() - kCx) / kF, (u.y() - kCy) / kF); };
  Frame f;
  int outliers_left = n_outliers;
  for (int i = 0; i < n_points; ++i) {
    const Eigen::Vector3d X(cube(rng), cube(rng), cube(rng));
    Eigen::Vector2d u = px(X) + Eigen::Vector2d(noise(rng), noise(rng));
    if (outliers_left > 0 && i % 2 == 0) {
      u += gross(rng) * Eigen::Vector2d(unit(rng), unit(rng)).normalized();
      --outliers_left;
    }
    f.points.push_back({X, norm(u), 0.5});
  }
  for (int i = 0; i < n_lines; ++i) {
    const Eigen::Vector3d A(cube(rng), cube(rng), cube(rng)), B(cube(rng), cube(rng), cube(rng));
    const Eigen::Vector2d a = px(A), b = px(B);
    const Eigen::Vector2d dir = (b - a).normalized(), across(-dir.y(), dir.x());
    Eigen::Vector2d a2 = a + noise(rng) * across, b2 = b + noise(rng) * across;
    if (outliers_left > 0 && i % 3 == 1) {
      const double s = gross(rng);
      a2 += s * across;
      b2 += s * across;
      --outliers_left;
    }
    f.lines.push_back({A, B, norm(a2), norm(b2), 0.5});
  }
  Vector6d d;
  d << 0.012, -0.01, 0.012, 0.05, 0.04, -0.05;  // ~2 cm, ~5 degrees
  f.T_init = SE3::exp(d) * T;
  return f;
}

/// make_frame() plus two circles of 6 cm radius (12 edge points each), 6 stereo points (2 mm)
/// and 3 region normals (0.02 rad); the start pose 1 cm and 2.5 degrees off.
Frame make_mixed_frame(unsigned seed) {
  Frame f = make_frame(8, 20, 0, seed);
  std::mt19937 rng(seed + 1);
  std::uniform_real_distribution<double> cube(-0.15, 0.15);
  std::normal_distribution<double> noise(0.0, 0.5), n01(0.0, 1.0);
  const SE3 T = SE3::from_rvec({0.02, -0.01, 0.6}, {0.4, -0.3, 0.2});
  const auto norm_px = [&](const Eigen::Vector3d& X) {
    const Eigen::Vector3d p = T * X;
    return Eigen::Vector2d(p.x() / p.z() + noise(rng) / kF, p.y() / p.z() + noise(rng) / kF);
  };
  // On the face z = -0.15 and on a 45-degree chamfer, both facing the camera (40 - 50 degrees
  // from edge-on).
  const Eigen::Vector3d centres[2] = {{0.0, 0.0, -0.15}, {0.0, -0.1, -0.1}};
  const Eigen::Vector3d axes[2] = {Eigen::Vector3d::UnitZ(), Eigen::Vector3d(0.0, -1.0, -1.0).normalized()};
  for (int c = 0; c < 2; ++c) {
    const Eigen::Vector3d e1 = axes[c].unitOrthogonal(), e2 = axes[c].cross(e1);
    for (int k = 0; k < 12; ++k) {
      const double phi = 2.0 * 3.14159265358979 * k / 12.0;
      const Eigen::Vector3d X = centres[c] + 0.06 * (std::cos(phi) * e1 + std::sin(phi) * e2);
      f.circles.push_back({centres[c], axes[c], 0.06, norm_px(X), 0.5});
    }
  }
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3d X(cube(rng), cube(rng), cube(rng));
    f.points3d.push_back({X, T * X + 0.002 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng)), 0.002});
  }
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d n = Eigen::Vector3d(n01(rng), n01(rng), n01(rng)).normalized();
    const Eigen::Vector3d noise3(n01(rng), n01(rng), n01(rng));
    f.normals.push_back({n, (T.quaternion() * n + 0.02 * noise3).normalized(), 0.02});
  }
  Vector6d d;
  d << 0.006, -0.005, 0.006, 0.025, 0.02, -0.025;
  f.T_init = SE3::exp(d) * T;
  return f;
}

void run(benchmark::State& state, int n_outliers, bool robust_init) {
  const Frame f = make_frame(8, 20, n_outliers, 5);
  PoseSolverParams p;
  p.focal_px = kF;
  p.robust_init = robust_init;
  PoseSolver solver(p);
  solver.reserve(f.points.size(), f.lines.size());
  std::vector<std::uint8_t> pin(f.points.size()), lin(f.lines.size());
  PoseResult r;
  for (auto _ : state) {
    r = solver.solve(f.T_init, f.points, f.lines, pin, lin);
    benchmark::DoNotOptimize(r);
  }
  state.counters["iterations"] = r.iterations;
  state.counters["inliers"] = r.inliers;
  state.counters["ok"] = r.ok() ? 1 : 0;
}

void BM_PoseSolve_Mixed(benchmark::State& state) {
  const Frame f = make_mixed_frame(5);
  PoseSolverParams p;
  p.focal_px = kF;
  PoseSolver solver(p);
  solver.reserve(f.points.size(), f.lines.size(), f.circles.size(), f.points3d.size(), f.normals.size());
  ObservationSet obs;
  obs.points = f.points;
  obs.lines = f.lines;
  obs.circles = f.circles;
  obs.points3d = f.points3d;
  obs.normals = f.normals;
  PoseResult r;
  for (auto _ : state) {
    r = solver.solve(f.T_init, obs);
    benchmark::DoNotOptimize(r);
  }
  state.counters["iterations"] = r.iterations;
  state.counters["inliers"] = r.inliers;
  state.counters["ok"] = r.ok() ? 1 : 0;
}

void BM_PoseFilter_PredictUpdate(benchmark::State& state) {
  v4r::filter::PoseFilter filter;
  v4r::geometry::Matrix6d cov = v4r::geometry::Matrix6d::Zero();
  cov.diagonal() << 1e-6, 1e-6, 1e-6, 1e-5, 1e-5, 1e-5;
  SE3 T = SE3::from_rvec({0.02, -0.01, 0.6}, {0.4, -0.3, 0.2});
  Vector6d vel;
  vel << 0.05, 0.0, 0.02, 0.1, -0.2, 0.1;
  const SE3 step = SE3::exp(vel / 30.0);
  const SE3 T0 = T;
  filter.reset(T, cov);
  double chi2 = 0.0;
  int frame = 0;
  for (auto _ : state) {
    if (++frame == 300) {  // 10 s of motion, then start over
      frame = 0;
      T = T0;
      filter.reset(T, cov);
    }
    T = step * T;
    filter.predict(1.0 / 30.0);
    chi2 = filter.update(T, cov);
    benchmark::DoNotOptimize(chi2);
  }
  state.counters["chi2"] = chi2;
}

void BM_PoseSolve_20Lines8Points(benchmark::State& s) { run(s, 0, true); }
void BM_PoseSolve_20Lines8Points_5Outliers(benchmark::State& s) { run(s, 5, true); }
void BM_PoseSolve_20Lines8Points_NoRobustInit(benchmark::State& s) { run(s, 0, false); }
void BM_PoseSolve_20Lines8Points_5Outliers_NoRobustInit(benchmark::State& s) { run(s, 5, false); }

}  // namespace

BENCHMARK(BM_PoseSolve_20Lines8Points);
BENCHMARK(BM_PoseSolve_20Lines8Points_5Outliers);
BENCHMARK(BM_PoseSolve_20Lines8Points_NoRobustInit);
BENCHMARK(BM_PoseSolve_20Lines8Points_5Outliers_NoRobustInit);
BENCHMARK(BM_PoseSolve_Mixed);
BENCHMARK(BM_PoseFilter_PredictUpdate);
