// v4r - robust model-based object tracking. MIT licence.
// One solve over the observations of several cameras (ObservationSet::cameras): the pose is
// T_ref_obj, each camera sees T_cam_ref * T_ref_obj.
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

/// The 12 edges of a 0.2 m box centred at the object origin.
std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> box_edges() {
  std::vector<Eigen::Vector3d> c;
  for (int i = 0; i < 8; ++i) c.emplace_back((i & 1 ? 0.1 : -0.1), (i & 2 ? 0.1 : -0.1), (i & 4 ? 0.1 : -0.1));
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> e;
  for (int i = 0; i < 8; ++i)
    for (int b = 1; b < 8; b <<= 1)
      if (!(i & b)) e.emplace_back(c[static_cast<std::size_t>(i)], c[static_cast<std::size_t>(i | b)]);
  return e;
}

/// A line observation of edge (A, B) by a camera at T_cam_obj with `noise_px` Gaussian noise
/// on the two image points across the line.
LineObservation observe(const SE3& T_cam_obj, const Eigen::Vector3d& A, const Eigen::Vector3d& B, double noise_px,
                        std::mt19937& rng, std::uint8_t camera) {
  std::normal_distribution<double> n(0.0, noise_px);
  const auto project = [&](const Eigen::Vector3d& X) {
    const Eigen::Vector3d p = T_cam_obj * X;
    return Eigen::Vector2d(kF * p.x() / p.z() + kCx, kF * p.y() / p.z() + kCy);
  };
  const Eigen::Vector2d a = project(A), b = project(B);
  const Eigen::Vector2d d = (b - a).normalized(), nrm(-d.y(), d.x());
  const Eigen::Vector2d a2 = a + n(rng) * nrm, b2 = b + n(rng) * nrm;
  LineObservation o;
  o.X1_obj = A;
  o.X2_obj = B;
  o.xn1 = Eigen::Vector2d((a2.x() - kCx) / kF, (a2.y() - kCy) / kF);
  o.xn2 = Eigen::Vector2d((b2.x() - kCx) / kF, (b2.y() - kCy) / kF);
  o.sigma_px = 0.5;
  o.camera = camera;
  return o;
}

double rotation_error(const SE3& a, const SE3& b) { return (a * b.inverse()).log().tail<3>().norm(); }
double translation_error(const SE3& a, const SE3& b) { return (a.translation() - b.translation()).norm(); }

struct Rig {
  SE3 T_ref_obj = SE3::from_rvec(Eigen::Vector3d(0.03, -0.02, 0.55), Eigen::Vector3d(0.5, -0.4, 0.3));
  SE3 T_ref_left;  // left camera = reference frame
  // Right camera 12 cm to the right, toed in by 5 degrees.
  SE3 T_ref_right = SE3::from_rvec(Eigen::Vector3d(0.12, 0.0, 0.0), Eigen::Vector3d(0.0, -0.087, 0.0));
  std::vector<SolveCamera> cameras() const {
    return {SolveCamera{T_ref_left.inverse(), kF}, SolveCamera{T_ref_right.inverse(), kF}};
  }
};

PoseSolverParams params() {
  PoseSolverParams p;
  p.focal_px = kF;
  return p;
}

}  // namespace

TEST(MultiCameraSolve, TwoCamerasRecoverThePoseFromAPerturbedStart) {
  const Rig rig;
  std::mt19937 rng(1);
  std::vector<LineObservation> lines;
  for (const auto& [A, B] : box_edges()) {
    lines.push_back(observe(rig.T_ref_left.inverse() * rig.T_ref_obj, A, B, 0.3, rng, 0));
    lines.push_back(observe(rig.T_ref_right.inverse() * rig.T_ref_obj, A, B, 0.3, rng, 1));
  }
  const std::vector<SolveCamera> cams = rig.cameras();
  ObservationSet obs;
  obs.lines = lines;
  obs.cameras = cams;
  Vector6d d;
  d << 0.01, -0.008, 0.02, 0.05, -0.04, 0.03;
  PoseSolver solver(params());
  const PoseResult r = solver.solve(SE3::exp(d) * rig.T_ref_obj, obs);
  ASSERT_TRUE(r.ok());
  EXPECT_LT(translation_error(r.T_cam_obj, rig.T_ref_obj), 1e-3);
  EXPECT_LT(rotation_error(r.T_cam_obj, rig.T_ref_obj), 3e-3);
  EXPECT_EQ(r.inliers, static_cast<int>(lines.size()));
  EXPECT_LT(r.rms_px, 1.0);
}

TEST(MultiCameraSolve, ObservationsOfACameraAwayFromTheReferenceAloneGiveTheReferencePose) {
  // Only the right camera observes: the solved pose is still T_ref_obj (checks the camera
  // transform and the Jacobian's adjoint: a wrong one converges elsewhere or not at all).
  const Rig rig;
  std::mt19937 rng(2);
  std::vector<LineObservation> lines;
  for (const auto& [A, B] : box_edges()) lines.push_back(observe(rig.T_ref_right.inverse() * rig.T_ref_obj, A, B, 0.0, rng, 1));
  const std::vector<SolveCamera> cams = rig.cameras();
  ObservationSet obs;
  obs.lines = lines;
  obs.cameras = cams;
  Vector6d d;
  d << -0.02, 0.01, 0.03, -0.08, 0.06, 0.05;
  PoseSolver solver(params());
  const PoseResult r = solver.solve(SE3::exp(d) * rig.T_ref_obj, obs);
  ASSERT_TRUE(r.ok());
  EXPECT_LT(translation_error(r.T_cam_obj, rig.T_ref_obj), 1e-7);
  EXPECT_LT(rotation_error(r.T_cam_obj, rig.T_ref_obj), 1e-7);
  EXPECT_GT(r.iterations, 1);
}

TEST(MultiCameraSolve, OneCameraAtTheReferenceEqualsTheSingleCameraSolve) {
  const Rig rig;
  std::mt19937 rng(3);
  std::vector<LineObservation> lines;
  for (const auto& [A, B] : box_edges()) lines.push_back(observe(rig.T_ref_obj, A, B, 0.4, rng, 0));
  const std::vector<SolveCamera> one = {SolveCamera{SE3(), kF}};
  ObservationSet single, multi;
  single.lines = multi.lines = lines;
  multi.cameras = one;
  Vector6d d;
  d << 0.005, 0.005, -0.01, 0.02, 0.02, -0.02;
  PoseSolver s1(params()), s2(params());
  const PoseResult a = s1.solve(SE3::exp(d) * rig.T_ref_obj, single);
  const PoseResult b = s2.solve(SE3::exp(d) * rig.T_ref_obj, multi);
  ASSERT_TRUE(a.ok());
  ASSERT_TRUE(b.ok());
  EXPECT_LT(translation_error(a.T_cam_obj, b.T_cam_obj), 1e-9);
  EXPECT_LT(rotation_error(a.T_cam_obj, b.T_cam_obj), 1e-9);
  EXPECT_LT((a.covariance - b.covariance).norm(), 1e-9 * a.covariance.norm());
}

TEST(MultiCameraSolve, StereoIsMoreCertainInDepthThanOneCamera) {
  // Covariance: the second camera's baseline fixes depth far better than one camera's focal
  // length does.
  const Rig rig;
  std::mt19937 rng(4);
  std::vector<LineObservation> left, both;
  for (const auto& [A, B] : box_edges()) {
    left.push_back(observe(rig.T_ref_obj, A, B, 0.3, rng, 0));
    both.push_back(left.back());
    both.push_back(observe(rig.T_ref_right.inverse() * rig.T_ref_obj, A, B, 0.3, rng, 1));
  }
  const std::vector<SolveCamera> cams = rig.cameras();
  ObservationSet mono, stereo;
  mono.lines = left;
  stereo.lines = both;
  stereo.cameras = cams;
  PoseSolver s1(params()), s2(params());
  const PoseResult a = s1.solve(rig.T_ref_obj, mono);
  const PoseResult b = s2.solve(rig.T_ref_obj, stereo);
  ASSERT_TRUE(a.ok());
  ASSERT_TRUE(b.ok());
  EXPECT_LT(b.covariance(2, 2), 0.6 * a.covariance(2, 2));
}

TEST(MultiCameraSolve, ACameraThatSeesLittleStillContributes) {
  // The left camera sees only the four edges along the object's x axis (parallel: rotation about
  // x and translation along x are not fixed, the solve alone is degenerate); the right camera sees two edges
  // along y. Together: the full pose.
  const Rig rig;
  std::mt19937 rng(5);
  std::vector<LineObservation> left, both;
  for (const auto& [A, B] : box_edges()) {
    const Eigen::Vector3d dir = (B - A).normalized();
    if (std::abs(dir.x()) > 0.9) left.push_back(observe(rig.T_ref_obj, A, B, 0.2, rng, 0));
    if (std::abs(dir.y()) > 0.9 && A.z() > 0.0) both.push_back(observe(rig.T_ref_right.inverse() * rig.T_ref_obj, A, B, 0.2, rng, 1));
  }
  ASSERT_EQ(left.size(), 4u);
  ASSERT_EQ(both.size(), 2u);
  both.insert(both.end(), left.begin(), left.end());
  ObservationSet mono;
  mono.lines = left;
  PoseSolver s1(params());
  Vector6d d;
  d << 0.004, -0.003, 0.006, 0.01, 0.01, -0.01;
  const PoseResult m = s1.solve(SE3::exp(d) * rig.T_ref_obj, mono);
  const std::vector<SolveCamera> cams = rig.cameras();
  ObservationSet stereo;
  stereo.lines = both;
  stereo.cameras = cams;
  PoseSolver s2(params());
  const PoseResult r = s2.solve(SE3::exp(d) * rig.T_ref_obj, stereo);
  ASSERT_TRUE(r.ok());
  EXPECT_LT(translation_error(r.T_cam_obj, rig.T_ref_obj), 2e-3);
  EXPECT_LT(rotation_error(r.T_cam_obj, rig.T_ref_obj), 5e-3);
  // Alone, the left camera leaves the slide along the edges to noise (degenerate, or a variance
  // along the object's x axis far above the stereo solve's).
  if (m.ok()) {
    const Eigen::Vector3d x_axis = rig.T_ref_obj.rotation().col(0);
    const double var_mono = x_axis.dot(m.covariance.topLeftCorner<3, 3>() * x_axis);
    const double var_stereo = x_axis.dot(r.covariance.topLeftCorner<3, 3>() * x_axis);
    EXPECT_GT(var_mono, 100.0 * var_stereo);
  }
}

TEST(MultiCameraSolve, AnObservationOfAnUnknownCameraIsInvalid) {
  const Rig rig;
  std::mt19937 rng(6);
  std::vector<LineObservation> lines;
  for (const auto& [A, B] : box_edges()) lines.push_back(observe(rig.T_ref_obj, A, B, 0.2, rng, 0));
  lines[3].camera = 2;  // only cameras 0 and 1 exist
  const std::vector<SolveCamera> cams = rig.cameras();
  ObservationSet obs;
  obs.lines = lines;
  obs.cameras = cams;
  std::vector<std::uint8_t> inlier(lines.size(), 1);
  InlierFlags flags;
  flags.lines = inlier;
  PoseSolver solver(params());
  const PoseResult r = solver.solve(rig.T_ref_obj, obs, flags);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(inlier[3], 0);
  EXPECT_EQ(r.inliers, static_cast<int>(lines.size()) - 1);
  // A camera with a non-finite pose makes the solve fail instead of producing garbage.
  std::vector<SolveCamera> bad = cams;
  bad[1].T_cam_ref = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(std::nan(""), 0.0, 0.0));
  obs.cameras = bad;
  EXPECT_FALSE(solver.solve(rig.T_ref_obj, obs).ok());
}
