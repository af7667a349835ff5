// v4r - robust model-based object tracking. MIT licence.
// ViewPredictor, cue integration: an edge not found in the last frame is searched with the colour
// learned on the same face by an edge that was (CycleParams::share_face_appearance).
#include <memory>
#include <string>
#include <utility>

#include <gtest/gtest.h>

#include "v4r/geometry/look_at.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/model/face_centroid.hpp"
#include "v4r/pipeline/view_predictor.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {
namespace {

/// A box's .cao text: x in [-hx, hx], y in [-hy, hy], z in [z0, z1] (metres), six faces.
std::string box_cao(double hx, double hy, double z0, double z1) {
  std::string s = "V1\n8\n";
  for (const double z : {z0, z1})
    for (const auto& [sx, sy] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}})
      s += std::to_string(sx * hx) + " " + std::to_string(sy * hy) + " " + std::to_string(z) + "\n";
  return s + "0\n0\n6\n4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 2 3 7 6\n4 1 2 6 5\n4 3 0 4 7\n0\n0\n";
}

const std::string kBox = box_cao(0.10, 0.075, -0.05, 0.05);

/// An object of the .cao text `cao` predicted at `T_pred` (no model when it does not parse).
scene::Object object_from_cao(const char* cao, const char* name, const geometry::SE3& T_pred) {
  scene::Object obj;
  auto m = model::parse_cao(cao, name);
  EXPECT_TRUE(m.has_value()) << name;
  if (m) obj.model = std::make_shared<const model::Model>(std::move(*m));
  obj.T_pred = T_pred;
  return obj;
}

/// A 640 x 480 camera.
scene::Camera camera_640x480(double fx, double fy, double cx, double cy) {
  scene::Camera cam;
  cam.intrinsics.width = 640;
  cam.intrinsics.height = 480;
  cam.intrinsics.fx = fx;
  cam.intrinsics.fy = fy;
  cam.intrinsics.cx = cx;
  cam.intrinsics.cy = cy;
  return cam;
}

/// One view of a camera, as the scene makes it: a line feature per model edge, no face seen yet.
scene::View fresh_view(const model::Model& m) {
  scene::View view;
  view.lines.resize(m.lines().size());
  for (std::size_t i = 0; i < view.lines.size(); ++i) view.lines[i].edge = static_cast<model::Index>(i);
  view.face_visible.assign(m.faces().size(), 0);
  return view;
}

struct Fixture {
  scene::Object obj = object_from_cao(kBox.c_str(), "box.cao", geometry::look_at(0.6, 0.5, 0.6));
  scene::Camera cam = camera_640x480(600, 600, 319.5, 239.5);
  scene::View view = obj.model ? fresh_view(*obj.model) : scene::View{};
  [[nodiscard]] bool object_side(std::size_t li, int k) const { return view.lines[li].track.side[k].is_object; }
};

features::SideAppearance green() {
  features::SideAppearance a;
  a.learned = true;
  a.channels = 3;
  a.mean[0] = 110.0f;
  a.mean[1] = 0.25f;
  a.mean[2] = 0.55f;
  a.var[0] = 25.0f;
  a.var[1] = a.var[2] = 1e-4f;
  return a;
}

TEST(ViewPredictor, AnEdgeNotFoundTakesTheColourItsFaceShowsOnAFoundEdge) {
  CycleParams p;
  Fixture f;
  ViewPredictor predictor(p);
  predictor.predict(f.obj, f.view, f.cam);
  // Two visible edges of one face (model face 1, the top z = +0.05, seen from above): edges
  // whose left or right face is face 1.
  const model::Model& m = *f.obj.model;
  int donor = -1, taker = -1;
  for (std::size_t li = 0; li < f.view.lines.size(); ++li) {
    const auto& e = m.lines()[li];
    if (!f.view.lines[li].visible || f.view.lines[li].ambiguous || (e.face_left != 1 && e.face_right != 1)) continue;
    (donor < 0 ? donor : taker) = static_cast<int>(li);
    if (taker >= 0) break;
  }
  ASSERT_GE(donor, 0);
  ASSERT_GE(taker, 0);
  ASSERT_TRUE(f.view.face_visible[1]);
  // The donor was found and learned the face's colour on its face-1 side; the taker was not
  // found and holds a stale grey appearance there.
  auto face1_side = [&](int li) {
    const Eigen::Vector2d a = f.view.lines[li].predicted.a, d = f.view.lines[li].predicted.b - a;
    const Eigen::Vector3d c = f.view.T_cam_obj * model::face_centroid(m, 1);
    return Eigen::Vector2d(-d.y(), d.x()).dot(f.cam.intrinsics.project(c) - a) > 0 ? 1 : 0;
  };
  const int kd = face1_side(donor), kt = face1_side(taker);
  ASSERT_TRUE(f.object_side(donor, kd));
  ASSERT_TRUE(f.object_side(taker, kt));
  f.view.lines[donor].status = scene::FeatureStatus::kFound;
  f.view.lines[donor].track.side[kd] = green();
  features::SideAppearance grey = green();
  grey.mean[1] = grey.mean[2] = 1.0f / 3.0f;
  f.view.lines[taker].status = scene::FeatureStatus::kLost;
  f.view.lines[taker].track.side[kt] = grey;

  predictor.predict(f.obj, f.view, f.cam);
  const features::SideAppearance& got = f.view.lines[taker].track.side[kt];
  EXPECT_TRUE(got.is_object);
  EXPECT_TRUE(got.learned);
  EXPECT_FLOAT_EQ(got.mean[1], 0.25f);
  EXPECT_FLOAT_EQ(got.mean[2], 0.55f);

  // A found edge keeps what it learned itself; with the option off, a lost one does too.
  f.view.lines[taker].status = scene::FeatureStatus::kFound;
  f.view.lines[taker].track.side[kt] = grey;
  predictor.predict(f.obj, f.view, f.cam);
  EXPECT_FLOAT_EQ(f.view.lines[taker].track.side[kt].mean[1], 1.0f / 3.0f);
  p.share_face_appearance = false;
  ViewPredictor off(p);
  f.view.lines[taker].status = scene::FeatureStatus::kLost;
  off.predict(f.obj, f.view, f.cam);
  EXPECT_FLOAT_EQ(f.view.lines[taker].track.side[kt].mean[1], 1.0f / 3.0f);
}

// A 10 x 10 x 2 cm plate seen from above (the development benchmark's flange_blur, frame 22): its
// front-left side face is a sliver; the face's short vertical edge at the left corner leaves the
// corner 18 degrees off the face's long top crease and stays within about 6 px of it over its
// 18 px. Its window always holds the crease, the stronger edge: it is left out.
TEST(ViewPredictor, AShortEdgeAlongALongerOneFromTheSameCornerIsLeftOut) {
  const char* plate = R"(V1
8
-0.05 -0.05 0.00
-0.05  0.05 0.00
 0.05  0.05 0.00
 0.05 -0.05 0.00
-0.05 -0.05 0.02
 0.05 -0.05 0.02
 0.05  0.05 0.02
-0.05  0.05 0.02
0
0
6
4 0 1 2 3
4 4 5 6 7
4 0 3 5 4
4 2 1 7 6
4 1 0 4 7
4 3 2 6 5
0
0
)";
  const scene::Object obj =
      object_from_cao(plate, "plate.cao",
                      geometry::SE3(Eigen::Quaterniond(0.395112785, 0.707698090, 0.546391252, -0.210964215),
                                    Eigen::Vector3d(-0.036455773, 0.012927776, 0.531658317)));
  ASSERT_NE(obj.model, nullptr);
  const scene::Camera cam = camera_640x480(600, 600, 320, 240);
  const auto predict = [&](double converging_px) {
    CycleParams p;
    p.converging_px = converging_px;
    scene::View view = fresh_view(*obj.model);
    ViewPredictor(p).predict(obj, view, cam);
    return view;
  };
  const scene::View on = predict(CycleParams{}.converging_px), off = predict(0.0);
  ASSERT_GE(CycleParams{}.converging_px, 4.0);
  // The corner edge (-0.05, -0.05, 0 .. 0.02), seen (at least its upper part).
  int corner = -1;
  for (std::size_t i = 0; i < off.lines.size(); ++i) {
    const auto& e = obj.model->lines()[i];
    const Eigen::Vector3d a = obj.model->junctions()[e.a].p, b = obj.model->junctions()[e.b].p;
    if (std::abs(a.x() + 0.05) < 1e-9 && std::abs(a.y() + 0.05) < 1e-9 && std::abs(b.x() + 0.05) < 1e-9 &&
        std::abs(b.y() + 0.05) < 1e-9)
      corner = static_cast<int>(i);
  }
  ASSERT_GE(corner, 0);
  const scene::LineFeature& c_off = off.lines[static_cast<std::size_t>(corner)];
  ASSERT_TRUE(c_off.visible);
  EXPECT_FALSE(c_off.ambiguous);
  EXPECT_GT((c_off.predicted.b - c_off.predicted.a).norm(), 8.0);
  EXPECT_TRUE(on.lines[static_cast<std::size_t>(corner)].ambiguous);
  // No other edge is left out by it: the long ones stay as they were.
  for (std::size_t i = 0; i < on.lines.size(); ++i) {
    if (static_cast<int>(i) == corner) continue;
    EXPECT_EQ(on.lines[i].ambiguous, off.lines[i].ambiguous) << "edge " << i;
  }
}

// ViSP's 84 mm cube as v4r tracked it at frame 174 of its real sequence (Debian's
// visp-images-data; camera as tests/data/visp_cube_camera.yaml), the prediction for frame 175:
// the front and top faces are seen at about 45 degrees, the left and right faces edge-on, just
// turned away. Their hidden far edges (grazing: slivers at most) project beside the front and top
// faces' silhouette edges, two beside each corner. Each silhouette edge is paired with the first
// of them; the second, hidden too, only widens its sigma. (Left out as "too crowded", the front
// face's two silhouette edges went, and the turn about the vertical axis was free: v4r's pose ran
// 4.5 degrees off there.)
TEST(ViewPredictor, HiddenEdgesOfAFaceTurningEdgeOnDoNotTakeTheSilhouetteOut) {
  const char* cube = R"(V1
8
 0.000  0.000  0.000
-0.084  0.000  0.000
-0.084  0.084  0.000
 0.000  0.084  0.000
 0.000  0.000  0.084
-0.084  0.000  0.084
-0.084  0.084  0.084
 0.000  0.084  0.084
0
0
6
4 0 4 5 1
4 1 5 6 2
4 6 7 3 2
4 3 7 4 0
4 0 1 2 3
4 7 6 5 4
0
0
)";
  const scene::Object obj = object_from_cao(
      cube, "cube.cao",
      geometry::SE3(Eigen::Quaterniond(0.390383825, 0.920643015, -0.00232692269, 0.00339023125).normalized(),
                    Eigen::Vector3d(0.0299028137, -0.0533262504, 0.692615449)));
  ASSERT_NE(obj.model, nullptr);
  const scene::Camera cam = camera_640x480(547.7367575, 542.0744058, 338.7036994, 234.5083345);
  scene::View view = fresh_view(*obj.model);
  CycleParams p;
  ViewPredictor predictor(p);
  predictor.predict(obj, view, cam);  // the faces' visibility settles (hysteresis) on the first call
  predictor.predict(obj, view, cam);
  const auto edge = [&](int a, int b) -> const scene::LineFeature& {
    for (const scene::LineFeature& f : view.lines) {
      const auto& e = obj.model->lines()[f.edge];
      if ((static_cast<int>(e.a) == a && static_cast<int>(e.b) == b) || (static_cast<int>(e.a) == b && static_cast<int>(e.b) == a))
        return f;
    }
    ADD_FAILURE() << "no edge " << a << "-" << b;
    return view.lines[0];
  };
  // The situation: the side faces' far edges are hidden and grazing.
  for (const auto& [a, b] : {std::pair{6, 2}, {2, 1}, {7, 3}, {0, 3}}) {
    EXPECT_FALSE(edge(a, b).visible) << a << "-" << b;
    EXPECT_TRUE(edge(a, b).grazing) << a << "-" << b;
  }
  // All seven visible edges are tracked: top, crease, bottom and the four silhouette edges.
  int tracked = 0;
  for (const auto& [a, b] : {std::pair{6, 7}, {4, 5}, {0, 1}, {5, 6}, {5, 1}, {7, 4}, {4, 0}}) {
    const scene::LineFeature& f = edge(a, b);
    EXPECT_TRUE(f.visible) << a << "-" << b;
    EXPECT_FALSE(f.ambiguous) << a << "-" << b;
    tracked += f.visible && !f.ambiguous ? 1 : 0;
  }
  EXPECT_EQ(tracked, 7);
  // The front face's silhouette edges: paired with a hidden edge, their sigma covers both.
  for (const auto& [a, b] : {std::pair{5, 1}, {4, 0}}) {
    EXPECT_TRUE(edge(a, b).merged) << a << "-" << b;
    EXPECT_GT(edge(a, b).sigma_px, p.line_sigma_px) << a << "-" << b;
    // A whole side face between them, no thin one: measured at the visible edge, not as a pair.
    EXPECT_EQ(edge(a, b).range.pair_span, 0.0) << a << "-" << b;
  }
}

TEST(ViewPredictor, AThinPlatesEdgeFaceIsMeasuredAsAPairAtItsCentre) {
  // A plate 30 x 20 cm, 1 cm thick, seen from above its top edge face at about 1 m: the face's
  // two long edges 3-4 px apart, tracked as one against their mid-line and measured at the
  // centre between them (cycle.pair_span), as a blurred thin plate needs.
  const std::string plate = box_cao(0.15, 0.10, 0.0, 0.01);
  const scene::Object obj = object_from_cao(
      plate.c_str(), "plate.cao",
      geometry::look_at(Eigen::Vector3d(0.05, 0.6, 0.9), Eigen::Vector3d(0.0, 0.0, 0.005), Eigen::Vector3d::UnitY()));
  ASSERT_NE(obj.model, nullptr);
  const scene::Camera cam = camera_640x480(600, 600, 319.5, 239.5);
  scene::View view = fresh_view(*obj.model);
  CycleParams p;
  ViewPredictor predictor(p);
  predictor.predict(obj, view, cam);
  predictor.predict(obj, view, cam);
  const scene::LineFeature* pair = nullptr;
  for (const scene::LineFeature& f : view.lines) {
    const auto& e = obj.model->lines()[f.edge];
    const bool top_face = (e.a == 2 && e.b == 3) || (e.a == 3 && e.b == 2) || (e.a == 6 && e.b == 7) || (e.a == 7 && e.b == 6);
    if (top_face && f.merged) pair = &f;
  }
  ASSERT_NE(pair, nullptr) << "the top edge face's edges are not tracked as one";
  EXPECT_EQ(pair->range.pair_span, p.pair_span_px);
  // Off, the pair's visible edge is measured.
  CycleParams off = p;
  off.pair_span_px = 0.0;
  ViewPredictor predictor_off(off);
  scene::View view_off = fresh_view(*obj.model);
  predictor_off.predict(obj, view_off, cam);
  predictor_off.predict(obj, view_off, cam);
  for (const scene::LineFeature& f : view_off.lines) EXPECT_EQ(f.range.pair_span, 0.0);
}

}  // namespace
}  // namespace v4r::pipeline
