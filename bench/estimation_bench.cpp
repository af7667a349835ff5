// v4r - robust model-based object tracking. MIT licence.
//
// Micro benchmarks of the object-space pose solver (estimation::PoseSolver::solve): a typical
// tracking frame of 20 edges + 8 points, clean and with 5 gross outliers, from a start pose 2 cm
// and 5 degrees off.
#include <cmath>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "v4r/estimation/pose_solver.hpp"

namespace {

using v4r::estimation::LineObservation;
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

void BM_PoseSolve_20Lines8Points(benchmark::State& s) { run(s, 0, true); }
void BM_PoseSolve_20Lines8Points_5Outliers(benchmark::State& s) { run(s, 5, true); }
void BM_PoseSolve_20Lines8Points_NoRobustInit(benchmark::State& s) { run(s, 0, false); }
void BM_PoseSolve_20Lines8Points_5Outliers_NoRobustInit(benchmark::State& s) { run(s, 5, false); }

}  // namespace

BENCHMARK(BM_PoseSolve_20Lines8Points);
BENCHMARK(BM_PoseSolve_20Lines8Points_5Outliers);
BENCHMARK(BM_PoseSolve_20Lines8Points_NoRobustInit);
BENCHMARK(BM_PoseSolve_20Lines8Points_5Outliers_NoRobustInit);
