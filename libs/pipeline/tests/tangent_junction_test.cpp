// v4r - robust model-based object tracking. MIT licence.
// Line-arc junctions with a common tangent (paper 3.3): a slotted plate (a stadium: two straight
// edges joined by two half circles) has four junctions where the edges run into the arcs along
// their tangent. They cannot be intersected; they are validated by the closeness of the two
// measured edges and enter the solve as point observations.
#include <cmath>

#include <gtest/gtest.h>

#include "v4r/geometry/look_at.hpp"
#include "v4r/model/model.hpp"
#include "v4r/pipeline/evaluation.hpp"
#include "v4r/pipeline/tracker.hpp"
#include "v4r/synth/renderer.hpp"

using namespace v4r;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// A stadium-shaped plate: straight edges along x (half length `half`), half circles of radius
/// `r` at both ends, `h` thick; origin at the centre of the top face, z up. The curved sides are
/// tessellated faces (for rendering and occlusion) without lines; the model's features are the
/// top outline (two lines, two arcs) and the two straight bottom edges.
model::Model stadium(double half = 0.06, double r = 0.04, double h = 0.025, int segments = 24) {
  model::ModelBuilder b;
  // Outline, counter-clockwise seen from +z: the right arc from (half, -r) to (half, r), then the
  // left arc from (-half, r) to (-half, -r); the straight edges close the gaps between them.
  std::vector<Eigen::Vector2d> outline;
  for (const double cx : {half, -half}) {
    const double start = cx > 0.0 ? -0.5 * kPi : 0.5 * kPi;
    for (int k = 0; k <= segments; ++k) {
      const double th = start + kPi * k / segments;
      outline.emplace_back(cx + r * std::cos(th), r * std::sin(th));
    }
  }
  const std::size_t m = outline.size(), s = static_cast<std::size_t>(segments);
  std::vector<model::Index> top, bottom;
  for (const auto& p : outline) top.push_back(b.add_junction(Eigen::Vector3d(p.x(), p.y(), 0.0)));
  for (const auto& p : outline) bottom.push_back(b.add_junction(Eigen::Vector3d(p.x(), p.y(), -h)));
  const auto top_face = b.add_face(top, {}, 1e-6, model::FaceEdges::kSkip);
  const auto bottom_face = b.add_face(std::vector<model::Index>(bottom.rbegin(), bottom.rend()), {}, 1e-6,
                                      model::FaceEdges::kSkip);
  EXPECT_TRUE(top_face && bottom_face);
  std::vector<model::Index> side(m);
  for (std::size_t i = 0; i < m; ++i) {
    const std::size_t j = (i + 1) % m;
    const auto f = b.add_face({bottom[i], bottom[j], top[j], top[i]}, {}, 1e-6, model::FaceEdges::kSkip);
    EXPECT_TRUE(f.has_value());
    side[i] = *f;
  }
  // The straight edges: back from outline[s] = (half, r) to outline[s+1] = (-half, r), front from
  // outline[m-1] = (-half, -r) to outline[0] = (half, -r); top and bottom, with their faces.
  const std::size_t back = s, front = m - 1;
  for (const std::size_t i : {back, front}) {
    const std::size_t j = (i + 1) % m;
    const model::Index lt = b.add_line(top[i], top[j]), lb = b.add_line(bottom[i], bottom[j]);
    EXPECT_TRUE(b.set_line_faces(lt, *top_face, side[i]));
    EXPECT_TRUE(b.set_line_faces(lb, side[i], *bottom_face));
  }
  // Top rims: half circles ending exactly at the straight edges' ends, tangent to them there.
  for (const double cx : {half, -half}) {
    model::CircleArc arc;
    arc.center = Eigen::Vector3d(cx, 0.0, 0.0);
    arc.normal = Eigen::Vector3d::UnitZ();
    arc.x_axis = Eigen::Vector3d::UnitX();
    arc.radius = r;
    arc.start = cx > 0.0 ? -0.5 * kPi : 0.5 * kPi;
    arc.end = arc.start + kPi;
    arc.face = *top_face;
    b.add_arc(arc);
  }
  auto built = std::move(b).build();
  EXPECT_TRUE(built.has_value()) << (built ? "" : built.error().to_string());
  return std::move(*built);
}

}  // namespace

TEST(TangentJunctions, SlotOutlineJunctionsAreObservedAndTrackingStaysAccurate) {
  auto model = std::make_shared<const model::Model>(stadium());
  ASSERT_EQ(model->arcs().size(), 2u);
  ASSERT_EQ(model->lines().size(), 4u);
  const geometry::PinholeCamera cam = synth::default_camera();
  synth::TrajectorySpec spec;
  spec.frames = 60;
  spec.T0 = geometry::look_at(0.35, -0.5, 0.9);
  const auto truth = synth::make_trajectory(spec);
  synth::RenderOptions ro;
  ro.colour = false;
  synth::Renderer renderer(cam, ro);

  struct Outcome {
    pipeline::AccuracyStats acc;
    int tangent = 0, frames_with = 0;
  };
  const auto run = [&](bool junctions) {
    pipeline::CycleParams p;
    p.use_junctions = junctions;
    // The plate's top and bottom straight edges run side by side; tracked in split windows they
    // cost rotation accuracy here (0.46 instead of 0.125 degrees, an open item of issue 8), which
    // this test of the tangent junctions does not measure: they are left out as before.
    p.track_side_by_side = false;
    pipeline::SingleObjectTracker tracker(model, cam, p);
    tracker.set_pose(truth[0]);
    Outcome o;
    std::vector<geometry::SE3> est;
    for (int i = 0; i < spec.frames; ++i) {
      const cv::Mat img = renderer.render(*model, truth[i], i);
      const auto r = tracker.track(image::ImageView{img.ptr<std::uint8_t>(0), img.cols, img.rows, static_cast<int>(img.step[0])});
      est.push_back(r.T_cam_obj);
      o.tangent += r.report.tangent_junctions;
      o.frames_with += r.report.tangent_junctions > 0 ? 1 : 0;
    }
    o.acc = pipeline::evaluate(est, truth);
    return o;
  };
  const Outcome with = run(true), without = run(false);
  std::printf("[tangent] %d tangent junctions in %d/%d frames; mean t %.3f mm (max %.3f), r %.3f deg | without "
              "junctions %.3f mm, %.3f deg\n",
              with.tangent, with.frames_with, spec.frames, with.acc.mean_translation_m * 1e3,
              with.acc.max_translation_m * 1e3, with.acc.mean_rotation_deg, without.acc.mean_translation_m * 1e3,
              without.acc.mean_rotation_deg);
  EXPECT_EQ(without.tangent, 0);
  EXPECT_GE(with.frames_with, spec.frames * 9 / 10);  // the front two at least, in nearly every frame
  EXPECT_GE(with.tangent, 2 * spec.frames * 9 / 10);
  EXPECT_EQ(with.acc.successes, with.acc.frames);
  EXPECT_LT(with.acc.mean_translation_m, 1e-3);
  EXPECT_LT(with.acc.mean_rotation_deg, 0.3);
  // The tangent point is measured along the line only as well as the arc's end is (weak, hence
  // the large sigma): the junctions must not pull the pose off.
  EXPECT_LT(with.acc.mean_translation_m, 1.15 * without.acc.mean_translation_m);
}
