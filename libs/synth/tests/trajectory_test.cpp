// v4r - robust model-based object tracking. MIT licence.
#include <algorithm>
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "render_test_helpers.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::synth {
namespace {

using geometry::SE3;
using test::kDeg;

TrajectorySpec spec_at_half_metre() {
  TrajectorySpec s;
  s.T0 = geometry::look_at(Eigen::Vector3d(0.2, -0.4, 0.35), Eigen::Vector3d::Zero());
  return s;
}

TEST(Trajectory, StartsExactlyAtT0) {
  const TrajectorySpec s = spec_at_half_metre();
  const auto traj = make_trajectory(s);
  ASSERT_EQ(traj.size(), 120u);
  EXPECT_EQ(traj[0].translation(), s.T0.translation());
  EXPECT_EQ(traj[0].quaternion().coeffs(), s.T0.quaternion().coeffs());
  TrajectorySpec none;
  none.frames = 0;
  EXPECT_TRUE(make_trajectory(none).empty());
}

struct Motion {
  double mean_t = 0, max_t = 0, mean_r = 0, max_r = 0;  // metres, radians per frame
};

Motion inter_frame_motion(const std::vector<SE3>& traj) {
  Motion m;
  for (std::size_t i = 1; i < traj.size(); ++i) {
    const double dt = (traj[i].translation() - traj[i - 1].translation()).norm();
    const double dr = geometry::rotation_angle_between(traj[i], traj[i - 1]);
    m.mean_t += dt;
    m.mean_r += dr;
    m.max_t = std::max(m.max_t, dt);
    m.max_r = std::max(m.max_r, dr);
  }
  m.mean_t /= static_cast<double>(traj.size() - 1);
  m.mean_r /= static_cast<double>(traj.size() - 1);
  return m;
}

TEST(Trajectory, InterFrameMotionIsSmallAndScalesWithSpeed) {
  TrajectorySpec s = spec_at_half_metre();
  const Motion m1 = inter_frame_motion(make_trajectory(s));
  EXPECT_GT(m1.mean_t, 0.002);
  EXPECT_LT(m1.mean_t, 0.004);
  EXPECT_LT(m1.max_t, 0.006);
  EXPECT_GT(m1.mean_r, 0.3 * kDeg);
  EXPECT_LT(m1.mean_r, 0.6 * kDeg);
  EXPECT_LT(m1.max_r, 1.0 * kDeg);
  s.speed = 2.0;
  const Motion m2 = inter_frame_motion(make_trajectory(s));
  EXPECT_NEAR(m2.mean_t / m1.mean_t, 2.0, 0.3);
  EXPECT_NEAR(m2.mean_r / m1.mean_r, 2.0, 0.3);
}

TEST(Trajectory, IsSmoothAndStaysWithinTheAmplitudes) {
  const TrajectorySpec s = spec_at_half_metre();
  const auto traj = make_trajectory(s);
  const Eigen::Vector3d t0 = s.T0.translation();
  for (std::size_t i = 1; i + 1 < traj.size(); ++i) {
    // Second differences (accelerations) much smaller than the velocities.
    const Eigen::Vector3d acc = traj[i + 1].translation() - 2.0 * traj[i].translation() + traj[i - 1].translation();
    EXPECT_LT(acc.norm(), 3e-4) << i;
    const Eigen::Vector3d d = traj[i].translation() - t0;
    EXPECT_LE(std::abs(d.x()), 2.0 * s.translation_amp);
    EXPECT_LE(std::abs(d.y()), 2.0 * s.translation_amp);
    EXPECT_LE(std::abs(d.z()), 2.0 * s.depth_amp);
    EXPECT_LE(geometry::rotation_angle_between(traj[i], s.T0), std::sqrt(3.0) * 2.0 * s.rotation_amp);
  }
  // Uses its amplitudes (not a tiny wobble).
  double max_dx = 0, max_dz = 0, max_rot = 0;
  for (const SE3& T : traj) {
    max_dx = std::max(max_dx, std::abs(T.translation().x() - t0.x()));
    max_dz = std::max(max_dz, std::abs(T.translation().z() - t0.z()));
    max_rot = std::max(max_rot, geometry::rotation_angle_between(T, s.T0));
  }
  EXPECT_GT(max_dx, 0.5 * s.translation_amp);
  EXPECT_GT(max_dz, 0.5 * s.depth_amp);
  EXPECT_GT(max_rot, 0.5 * s.rotation_amp);
}

TEST(Trajectory, DoesNotRepeatWithin120Frames) {
  const TrajectorySpec s = spec_at_half_metre();
  const auto traj = make_trajectory(s);
  for (std::size_t i = 10; i < traj.size(); ++i) {
    const double dt = (traj[i].translation() - s.T0.translation()).norm();
    const double dr = geometry::rotation_angle_between(traj[i], s.T0);
    EXPECT_TRUE(dt > 0.01 || dr > 2.0 * kDeg) << "frame " << i << " is back at the start";
  }
}

TEST(Trajectory, RotatesAboutTheObjectOrigin) {
  TrajectorySpec s = spec_at_half_metre();
  s.translation_amp = 0.0;
  s.depth_amp = 0.0;
  const auto traj = make_trajectory(s);
  for (const SE3& T : traj) EXPECT_LT((T.translation() - s.T0.translation()).norm(), 1e-12);
  EXPECT_GT(geometry::rotation_angle_between(traj.back(), s.T0), 0.05);
}

}  // namespace
}  // namespace v4r::synth
