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
  explicit BoxView(const geometry::SE3& start_offset) {
    auto m = model::parse_cao(synth::box_cao(), "box");
    EXPECT_TRUE(m.has_value());
    obj.model = std::make_shared<const model::Model>(std::move(*m));
    cam.intrinsics = synth::default_camera();
    truth = geometry::look_at(0.55, -0.6, 0.75);
    synth::Renderer r(cam.intrinsics, synth::RenderOptions{});
    cv::cvtColor(r.render(*obj.model, truth, 0), grey, cv::COLOR_BGR2GRAY);
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
