// v4r - robust model-based object tracking. MIT licence.
// ObjectSolver: how many observations fix a pose. Junctions are intersections of tracked lines,
// so they add no independent observation: three lines and their two junctions fix nothing the
// three lines do not, and are not enough for a solve without the prediction (min_lines 4).
#include <gtest/gtest.h>

#include <array>

#include "v4r/pipeline/object_solver.hpp"

namespace v4r::pipeline {
namespace {

const geometry::SE3 kTruth = geometry::SE3::from_rvec({0.02, -0.01, 0.5}, {0.3, -0.4, 0.2});

Eigen::Vector2d project(const Eigen::Vector3d& X_obj) {
  const Eigen::Vector3d p = kTruth * X_obj;
  return p.head<2>() / p.z();
}

/// The cube's top face (0.1 m): corners and its four edges, corner k to k + 1.
const std::array<Eigen::Vector3d, 4> kCorners = {Eigen::Vector3d(0, 0, 0.1), Eigen::Vector3d(0.1, 0, 0.1),
                                                 Eigen::Vector3d(0.1, 0.1, 0.1), Eigen::Vector3d(0, 0.1, 0.1)};

ObservationBuffer buffer(int lines, int junctions) {
  ObservationBuffer buf;
  buf.reserve(1, 8, 8, 0);
  buf.cameras.push_back({geometry::SE3(), 600.0});
  for (int k = 0; k < lines; ++k) {
    estimation::LineObservation l;
    l.X1_obj = kCorners[k];
    l.X2_obj = kCorners[(k + 1) % 4];
    l.xn1 = project(l.X1_obj);
    l.xn2 = project(l.X2_obj);
    buf.lines.push_back(l);
    buf.line_refs.push_back({});
  }
  // Junction k joins edges k - 1 and k: corner k (k = 1 .. junctions).
  for (int k = 1; k <= junctions; ++k) {
    estimation::PointObservation p;
    p.X_obj = kCorners[k];
    p.xn = project(p.X_obj);
    buf.points.push_back(p);
  }
  return buf;
}

TEST(ObjectSolver, ThreeLinesAndTheirJunctionsDoNotFixAPoseWithoutThePrediction) {
  CycleParams p;
  p.min_lines = 4;
  ObjectSolver solver(p);
  solver.reserve(8, 8, 0);
  const geometry::SE3 start = geometry::SE3::from_rvec({0.025, -0.012, 0.51}, {0.31, -0.38, 0.21});
  ObservationBuffer three = buffer(3, 2);
  EXPECT_FALSE(solver.solve(start, three, SolvePrior{}).updated);  // 5 observations, 3 independent

  ObservationBuffer four = buffer(4, 2);
  const ObjectSolve s = solver.solve(start, four, SolvePrior{});
  ASSERT_TRUE(s.updated);
  EXPECT_LT((s.T_ref_obj.translation() - kTruth.translation()).norm(), 1e-6);

  // With a usable prediction, the three lines are solved with it as a prior (degraded, not lost).
  SolvePrior prior;
  prior.usable = true;
  prior.T_ref_obj = start;
  prior.covariance = geometry::Matrix6d::Identity() * 1e-4;
  ObservationBuffer again = buffer(3, 2);
  const ObjectSolve sp = solver.solve(start, again, prior);
  ASSERT_TRUE(sp.updated);
  EXPECT_TRUE(sp.prior_used);
}

}  // namespace
}  // namespace v4r::pipeline
