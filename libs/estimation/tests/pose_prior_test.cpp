// v4r - robust model-based object tracking. MIT licence.
// Tests of the pose prior: partial observability (features that fix fewer than six degrees of
// freedom) solved in the observed directions, the others kept from the prior.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "solver_test_helpers.hpp"
#include "v4r/estimation/pose_solver.hpp"

using namespace v4r::estimation;
using namespace v4r::estimation::test;
using v4r::geometry::Matrix6d;
using v4r::geometry::SE3;
using v4r::geometry::Vector6d;

namespace {

/// The image line of a model edge at pose T, moved across by `noise_px` (normalised coordinates).
LineObservation observe(const SE3& T, const Eigen::Vector3d& X1, const Eigen::Vector3d& X2, double noise_px) {
  const Eigen::Vector3d p1 = T * X1, p2 = T * X2;
  Eigen::Vector2d a = p1.head<2>() / p1.z(), b = p2.head<2>() / p2.z();
  const Eigen::Vector2d d = (b - a).normalized(), n(-d.y(), d.x());
  a += n * noise_px / kF;
  b += n * noise_px / kF;
  LineObservation o;
  o.X1_obj = X1;
  o.X2_obj = X2;
  o.xn1 = a;
  o.xn2 = b;
  o.sigma_px = 0.5;
  return o;
}

TEST(PosePrior, ThreeParallelEdgesFixTheirDirectionsThePriorTheRest) {
  // Three parallel edges of a box face (along x): translation along x and rotation about x's
  // image-invariant directions are not fixed by them. Without a prior the solve is degenerate;
  // with one it succeeds: the directions across the edges come from the image (the prior is
  // 5 mm / 3 degrees off), the direction along them stays at the prior's value.
  const SE3 truth = SE3::from_rvec(Eigen::Vector3d(0.01, -0.02, 0.5), Eigen::Vector3d(0.3, -0.2, 0.1));
  std::mt19937 rng(5);
  std::normal_distribution<double> px(0.0, 0.3);
  std::vector<LineObservation> lines;
  for (const double y : {-0.04, 0.0, 0.04})
    lines.push_back(observe(truth, Eigen::Vector3d(-0.05, y, 0.0), Eigen::Vector3d(0.05, y, 0.0), px(rng)));
  PoseSolverParams params;
  params.focal_px = kF;
  PoseSolver solver(params);

  Vector6d offset;
  offset << 0.005, -0.004, 0.003, 0.03, -0.04, 0.02;
  const SE3 prior_pose = SE3::exp(offset) * truth;
  ObservationSet obs;
  obs.lines = lines;
  const PoseResult without = solver.solve(prior_pose, obs);
  EXPECT_FALSE(without.ok());

  PosePrior prior;
  prior.T_cam_obj = prior_pose;
  Vector6d sd;
  sd << 0.01, 0.01, 0.01, 0.05, 0.05, 0.05;  // 1 cm, 3 degrees
  prior.information = sd.cwiseInverse().cwiseAbs2().asDiagonal();
  obs.prior = &prior;
  const PoseResult with = solver.solve(prior_pose, obs);
  ASSERT_TRUE(with.ok());
  EXPECT_EQ(with.inliers, 3);
  // Every edge is reprojected onto its image line (residuals at the noise level).
  EXPECT_LT(with.rms_px, 1.0);
  // The image fixed what it sees: the edges' lines of sight. Check a direction they fix: the
  // object's y axis (across the edges) in the image, and the distance (edge spacing).
  const Eigen::Vector3d c_true = truth * Eigen::Vector3d(0, 0, 0), c_est = with.T_cam_obj * Eigen::Vector3d(0, 0, 0);
  const Eigen::Vector3d y_true = truth.rotation().col(1), y_est = with.T_cam_obj.rotation().col(1);
  const Eigen::Vector3d x_true = truth.rotation().col(0);
  // Position across the edges (perpendicular to x and to the line of sight) within 1 mm.
  const Eigen::Vector3d across = x_true.cross(c_true.normalized()).normalized();
  EXPECT_LT(std::abs(across.dot(c_est - c_true)), 1e-3);
  EXPECT_LT(std::acos(std::min(1.0, y_true.dot(y_est))), 0.02);
  // The covariance is finite and tight across the edges, wide (near the prior's) along them. The
  // object origin moves by v + w x t under a left perturbation (v, w): its covariance is
  // J C J^T with J = [I, -hat(t)].
  const Eigen::Vector3d t = with.T_cam_obj.translation();
  Eigen::Matrix<double, 3, 6> J;
  J << Eigen::Matrix3d::Identity(), -v4r::geometry::hat(t);
  const Eigen::Matrix3d C = J * with.covariance * J.transpose();
  const Eigen::Vector3d along_cam = x_true;
  const double var_along = along_cam.dot(C * along_cam);
  const double var_across = across.dot(C * across);
  EXPECT_GT(var_along, 10.0 * var_across);
  EXPECT_LT(std::sqrt(var_along), 0.02);
}

TEST(PosePrior, AWrongEdgeAmongFewIsRejectedWithThePrior) {
  // Four edges, one of them 15 px off (a background edge taken for it): without a prior four
  // observations cannot single it out; with an accurate prior they can.
  const SE3 truth = SE3::from_rvec(Eigen::Vector3d(-0.02, 0.01, 0.6), Eigen::Vector3d(2.0, 0.4, -0.3));
  std::vector<LineObservation> lines = {
      observe(truth, Eigen::Vector3d(-0.05, -0.04, 0.0), Eigen::Vector3d(0.05, -0.04, 0.0), 0.2),
      observe(truth, Eigen::Vector3d(0.05, -0.04, 0.0), Eigen::Vector3d(0.05, 0.04, 0.0), -0.2),
      observe(truth, Eigen::Vector3d(0.05, 0.04, 0.0), Eigen::Vector3d(-0.05, 0.04, 0.0), 0.1),
      observe(truth, Eigen::Vector3d(-0.05, 0.04, 0.0), Eigen::Vector3d(-0.05, -0.04, 0.0), 15.0),
  };
  PoseSolverParams params;
  params.focal_px = kF;
  PoseSolver solver(params);
  Vector6d offset;
  offset << 0.001, -0.001, 0.001, 0.005, 0.004, -0.005;
  PosePrior prior;
  prior.T_cam_obj = SE3::exp(offset) * truth;
  Vector6d sd;
  sd << 0.002, 0.002, 0.002, 0.01, 0.01, 0.01;
  prior.information = sd.cwiseInverse().cwiseAbs2().asDiagonal();
  ObservationSet obs;
  obs.lines = lines;
  obs.prior = &prior;
  std::vector<std::uint8_t> inlier(lines.size(), 0);
  InlierFlags flags;
  flags.lines = inlier;
  const PoseResult r = solver.solve(prior.T_cam_obj, obs, flags);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(inlier[3], 0);
  EXPECT_EQ(inlier[0] + inlier[1] + inlier[2], 3);
  EXPECT_LT((r.T_cam_obj.translation() - truth.translation()).norm(), 2e-3);
}

}  // namespace
