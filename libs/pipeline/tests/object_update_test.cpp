// v4r - robust model-based object tracking. MIT licence.
// update_object: the status of a measurement the motion so far does not explain, and of one
// after a loss.
#include <gtest/gtest.h>

#include "v4r/pipeline/object_update.hpp"

using namespace v4r;

namespace {

/// Status reported for one measurement `shift_m` away from a filter resting at the identity
/// pose (1 mm, 0.06 degree uncertainty), with every visible feature used and `matched` % edge
/// evidence, the last frame's status being `before`. `lost_by_image` receives the frame's own verdict.
scene::TrackStatus status_after(double shift_m, const pipeline::CycleParams& p, int matched = 90,
                                scene::TrackStatus before = scene::TrackStatus::kTracking,
                                bool* lost_by_image = nullptr) {
  scene::Object obj;
  obj.views.emplace_back();
  obj.views[0].evidence_samples = 100;
  obj.views[0].evidence_matched = matched;
  const geometry::SE3 T0(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, 0.5));
  geometry::Matrix6d cov = geometry::Matrix6d::Zero();
  cov.diagonal() << 1e-6, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6;
  obj.filter.reset(T0, cov);
  obj.smoother.reset(T0, cov);
  obj.filter.hold_still(1e-3, 1e-2);  // (a filter that has tracked a while: the velocity known to 1 mm/s)
  obj.filter.predict(1.0 / 30.0);
  obj.smoother.predict(1.0 / 30.0);
  obj.status = obj.measured = before;
  pipeline::ObjectMeasurement m;
  m.solves = 1;
  m.T_ref_obj = geometry::SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, shift_m)) * T0;
  m.covariance = m.reported_covariance = 1e-2 * cov;  // 0.1 mm: a confident measurement
  pipeline::ObjectReport rep;
  rep.features_visible = rep.lines_used = 8;
  rep.rms_px = 0.3;
  pipeline::update_object(obj, m, p, rep, 1.0 / 30.0);
  EXPECT_EQ(rep.status, obj.status);
  if (lost_by_image != nullptr) *lost_by_image = obj.lost_by_image;
  return obj.status;
}

}  // namespace

TEST(ObjectUpdate, AMeasurementFarFromThePredictionIsUsedButNotReportedTracking) {
  const pipeline::CycleParams p;
  ASSERT_GT(p.recovery.jump_chi2, 0.0);
  EXPECT_EQ(status_after(0.0005, p), scene::TrackStatus::kTracking) << "0.5 mm: within the prediction";
  // 8 cm in depth in one frame (an edge image fitting a farther pose of a box under occlusion):
  // the pose is used, but the image's support alone does not make it `tracking`.
  EXPECT_EQ(status_after(0.08, p), scene::TrackStatus::kDegraded);
  pipeline::CycleParams off = p;
  off.recovery.jump_chi2 = 0.0;
  EXPECT_EQ(status_after(0.08, off), scene::TrackStatus::kTracking) << "without the test";
}

TEST(ObjectUpdate, ALostObjectStaysLostUntilTheImageConfirmsItAgain) {
  const pipeline::CycleParams p;
  ASSERT_LT(p.status.lost_evidence, 0.35);
  ASSERT_GT(p.status.return_evidence, 0.35);
  bool by_image = true;
  // 35 % of the model confirmed: enough to stay on (degraded) while tracking...
  EXPECT_EQ(status_after(0.0005, p, 35, scene::TrackStatus::kTracking, &by_image), scene::TrackStatus::kDegraded);
  EXPECT_FALSE(by_image);
  // ...but after a loss it is no return (the tracker fitting clutter near the held pose): lost,
  // though not lost by this frame alone (so the search does not count it).
  EXPECT_EQ(status_after(0.0005, p, 35, scene::TrackStatus::kLost, &by_image), scene::TrackStatus::kLost);
  EXPECT_FALSE(by_image);
  EXPECT_EQ(status_after(0.0005, p, 60, scene::TrackStatus::kLost, &by_image), scene::TrackStatus::kTracking);
  EXPECT_EQ(status_after(0.0005, p, 10, scene::TrackStatus::kTracking, &by_image), scene::TrackStatus::kLost);
  EXPECT_TRUE(by_image);
  pipeline::CycleParams off = p;
  off.status.return_evidence = off.status.lost_evidence;
  EXPECT_EQ(status_after(0.0005, off, 35, scene::TrackStatus::kLost), scene::TrackStatus::kDegraded)
      << "without the hysteresis";
}
