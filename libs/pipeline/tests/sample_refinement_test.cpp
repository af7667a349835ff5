// v4r - robust model-based object tracking. MIT licence.
// SampleRefiner: the per-sample measurement beside the line windows (issue 8).
#include <cmath>
#include <memory>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "v4r/geometry/look_at.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/sample_refinement.hpp"
#include "v4r/pipeline/view_predictor.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::pipeline {
namespace {

struct BoxView {
  scene::Object obj;
  scene::Camera cam;
  scene::View view;
  geometry::SE3 truth;
  cv::Mat grey;
  /// The box at look_at(0.55, -0.6, 0.75) in the reference frame, the start pose offset from it
  /// by `start_offset` (on the left), seen by a camera at T_ref_cam.
  explicit BoxView(const geometry::SE3& start_offset, const geometry::SE3& T_ref_cam = geometry::SE3{}) {
    auto m = model::parse_cao(synth::box_cao(), "box");
    EXPECT_TRUE(m.has_value());
    obj.model = std::make_shared<const model::Model>(std::move(*m));
    cam.intrinsics = synth::default_camera();
    cam.T_ref_cam = T_ref_cam;
    truth = geometry::look_at(0.55, -0.6, 0.75);
    synth::Renderer r(cam.intrinsics, synth::RenderOptions{});
    cv::cvtColor(r.render(*obj.model, T_ref_cam.inverse() * truth, 0), grey, cv::COLOR_BGR2GRAY);
    // The view predicted at the start pose, as the cycle predicts it.
    view.lines.resize(obj.model->lines().size());
    for (std::size_t i = 0; i < view.lines.size(); ++i) view.lines[i].edge = static_cast<model::Index>(i);
    view.face_visible.assign(obj.model->faces().size(), 0);
    obj.T_pred = start_offset * truth;
    CycleParams p;
    ViewPredictor(p).predict(obj, view, cam);
  }
  [[nodiscard]] image::ImageView image() const { return image::ImageView{grey.data, grey.cols, grey.rows, static_cast<int>(grey.step)}; }
};

double rotation_deg(const geometry::SE3& a, const geometry::SE3& b) {
  return Eigen::AngleAxisd((a.rotation().transpose() * b.rotation()).eval()).angle() * 180.0 / M_PI;
}

TEST(SampleRefiner, BringsAPoseTwoPixelsOffBackToTheRenderedBox) {
  // 3 mm sideways and 0.4 deg about the camera's axis: about two pixels at the box.
  geometry::Vector6d xi;
  xi << 0.003, -0.002, 0.0, 0.0, 0.0, 0.007;
  BoxView s(geometry::SE3::exp(xi));
  SampleRefineParams p;
  SampleRefiner refiner(p);
  refiner.reserve();
  geometry::SE3 T = s.view.T_cam_obj;
  const double start_mm = 1e3 * (T.translation() - s.truth.translation()).norm();
  ASSERT_TRUE(refiner.refine(*s.obj.model, s.view, s.cam.intrinsics, s.image(), 3.0, T));
  EXPECT_GT(refiner.samples(), 100u);
  const double end_mm = 1e3 * (T.translation() - s.truth.translation()).norm();
  EXPECT_GT(start_mm, 3.0);
  EXPECT_LT(end_mm, 1.0) << "from " << start_mm << " mm";
  EXPECT_LT(rotation_deg(T, s.truth), 0.1);
  // It stops when the step has become small, well before the iteration limit.
  EXPECT_GE(refiner.iterations(), 2);
  EXPECT_LT(refiner.iterations(), p.iterations) << "did not converge";
}

/// A second camera 12 cm to the right, toed in 5 degrees.
geometry::SE3 right_camera() {
  return geometry::SE3(Eigen::Quaterniond(Eigen::AngleAxisd(-5.0 * M_PI / 180.0, Eigen::Vector3d::UnitY())), Eigen::Vector3d(0.12, 0.0, 0.0));
}

/// Refines the object's pose in camera a's frame from a's predicted pose over the views of a
/// and b (b's camera relative to a's from their T_ref_cam), with up to 30 iterations.
struct TwoViewFit {
  static SampleRefineParams params() {
    SampleRefineParams q;
    q.iterations = 30;
    return q;
  }
  SampleRefineParams p = params();
  SampleRefiner refiner{p};
  geometry::SE3 T;
  bool refined = false;
  TwoViewFit(const BoxView& a, const BoxView& b) : T(a.view.T_cam_obj) {
    refiner.reserve();
    const SampleView views[] = {{&a.view, &a.cam.intrinsics, a.image(), 3.0, geometry::SE3{}},
                                {&b.view, &b.cam.intrinsics, b.image(), 3.0, b.cam.T_ref_cam.inverse() * a.cam.T_ref_cam}};
    refined = refiner.refine(*a.obj.model, views, T);
  }
};

TEST(SampleRefiner, TwoViewsMoveOnePose) {
  // 2 cm along the first camera's axis and 0.5 degrees: the first view sees the box a little
  // smaller, the second (toed in, 12 cm away) also sees it sideways.
  geometry::Vector6d xi;
  xi << 0.002, 0.0, 0.02, 0.0, 0.009, 0.0;
  const BoxView a(geometry::SE3::exp(xi)), b(geometry::SE3::exp(xi), right_camera());
  const double start_mm = 1e3 * (a.view.T_cam_obj.translation() - a.truth.translation()).norm();
  const TwoViewFit fit(a, b);
  ASSERT_TRUE(fit.refined);
  EXPECT_GT(fit.refiner.samples(), 200u) << "both views sampled (150 each at most)";
  const double end_mm = 1e3 * (fit.T.translation() - a.truth.translation()).norm();
  EXPECT_GT(start_mm, 15.0);
  EXPECT_LT(end_mm, 1.0) << "from " << start_mm << " mm";
  EXPECT_LT(rotation_deg(fit.T, a.truth), 0.1);
  EXPECT_LT(fit.refiner.iterations(), fit.p.iterations) << "did not converge";
}

/// A camera swung 60 degrees about the vertical through the box (camera A's y axis): the box seen
/// from another side at the same distance.
geometry::SE3 swung_camera() {
  const Eigen::Vector3d c = geometry::look_at(0.55, -0.6, 0.75).translation();
  const geometry::SE3 swing(Eigen::Quaterniond(Eigen::AngleAxisd(60.0 * M_PI / 180.0, Eigen::Vector3d::UnitY())), Eigen::Vector3d::Zero());
  return geometry::SE3(Eigen::Quaterniond::Identity(), c) * swing * geometry::SE3(Eigen::Quaterniond::Identity(), -c);
}

TEST(SampleRefiner, ASecondViewAloneMovesTheFirstCamerasPose) {
  // The first camera's image is blank: only the second view's samples find edges, and their
  // Jacobians must be carried into the first camera's frame (60 degrees turned) for the pose to
  // come back.
  geometry::Vector6d xi;
  xi << 0.003, -0.002, 0.0, 0.0, 0.0, 0.007;
  BoxView a(geometry::SE3::exp(xi));
  const BoxView b(geometry::SE3::exp(xi), swung_camera());
  a.grey.setTo(128);
  const double start_mm = 1e3 * (a.view.T_cam_obj.translation() - a.truth.translation()).norm();
  const TwoViewFit fit(a, b);
  ASSERT_TRUE(fit.refined);
  const double end_mm = 1e3 * (fit.T.translation() - a.truth.translation()).norm();
  EXPECT_GT(start_mm, 3.0);
  EXPECT_LT(end_mm, 1.0) << "from " << start_mm << " mm";
  // As close as this view alone brings its own camera's pose (0.24 deg, refined by itself).
  EXPECT_LT(rotation_deg(fit.T, a.truth), 0.5);
}

TEST(SampleRefiner, OnAnImageWithoutEdgesThePoseStays) {
  geometry::Vector6d xi;
  xi << 0.003, 0.0, 0.0, 0.0, 0.0, 0.0;
  BoxView s(geometry::SE3::exp(xi));
  SampleRefiner refiner(SampleRefineParams{});
  refiner.reserve();
  geometry::SE3 T = s.view.T_cam_obj;
  const geometry::SE3 T0 = T;
  s.grey.setTo(128);  // no edge anywhere: no sample finds a gradient
  EXPECT_FALSE(refiner.refine(*s.obj.model, s.view, s.cam.intrinsics, s.image(), 3.0, T));
  EXPECT_EQ((T.translation() - T0.translation()).norm(), 0.0);
}

TEST(SampleRefiner, WithoutReserveOrImageItRefusesAndKeepsThePose) {
  BoxView s{geometry::SE3{}};
  SampleRefiner refiner(SampleRefineParams{});
  geometry::SE3 T = s.view.T_cam_obj;
  EXPECT_FALSE(refiner.refine(*s.obj.model, s.view, s.cam.intrinsics, s.image(), 3.0, T));  // no buffer
  refiner.reserve();
  EXPECT_FALSE(refiner.refine(*s.obj.model, s.view, s.cam.intrinsics, image::ImageView{}, 3.0, T));
  EXPECT_EQ((T.translation() - s.view.T_cam_obj.translation()).norm(), 0.0);
}

}  // namespace
}  // namespace v4r::pipeline
