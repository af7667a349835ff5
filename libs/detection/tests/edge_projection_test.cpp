// v4r - robust model-based object tracking. MIT licence.
// Edge samples of a projected model: hidden-line removal by faces and cylinders, normals.
#include <array>

#include <gtest/gtest.h>

#include "v4r/detection/edge_projection.hpp"
#include "v4r/geometry/look_at.hpp"
#include "v4r/geometry/polygon.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/synth/renderer.hpp"

using namespace v4r;
using namespace v4r::detection;

namespace {
model::Model load(const std::string& text) {
  auto m = model::parse_cao(text, "m");
  EXPECT_TRUE(m) << m.error().to_string();
  return std::move(*m);
}
}  // namespace

TEST(EdgeProjector, BoxFromAboveHidesTheEdgesOfTheFarBottomCorner) {
  const model::Model box = load(synth::box_cao());
  const geometry::PinholeCamera cam = synth::default_camera();
  // From elevation 40 deg, azimuth 30 deg: the corner (-x, -y, -z) is the one hidden.
  const geometry::SE3 T = geometry::look_at(0.7, 0.52, 0.7);
  EdgeProjector proj(box, 0.17);
  std::vector<EdgeSample> s(1000);
  const std::size_t n = proj.sample(T, cam, 4.0, s);
  ASSERT_GT(n, 100u);
  const Eigen::Vector3d hidden_corner(-0.10, -0.075, -0.05);
  int on_hidden = 0, on_top = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& p = s[i].p_obj;
    // On one of the three edges through the hidden corner: two of its coordinates equal the corner's.
    const int same = (std::abs(p.x() - hidden_corner.x()) < 1e-9) + (std::abs(p.y() - hidden_corner.y()) < 1e-9) +
                     (std::abs(p.z() - hidden_corner.z()) < 1e-9);
    if (same >= 2) ++on_hidden;
    if (std::abs(p.z() - 0.05) < 1e-9) ++on_top;
    EXPECT_NEAR(s[i].normal.norm(), 1.0, 1e-9);
    EXPECT_TRUE(cam.in_image(s[i].px));
  }
  EXPECT_EQ(on_hidden, 0);
  EXPECT_GT(on_top, n / 4);
}

TEST(EdgeProjector, NormalsArePerpendicularToTheProjectedEdges) {
  const model::Model box = load(synth::box_cao());
  const geometry::PinholeCamera cam = synth::default_camera();
  const geometry::SE3 T = geometry::look_at(0.7, 0.3, 0.6);
  EdgeProjector proj(box, 0.17);
  std::vector<EdgeSample> s(500);
  const std::size_t n = proj.sample(T, cam, 6.0, s);
  ASSERT_GT(n, 20u);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    if (s[i].piece != s[i + 1].piece) continue;
    const Eigen::Vector2d d = (s[i + 1].px - s[i].px).normalized();
    EXPECT_LT(std::abs(d.dot(s[i].normal)), 0.05);  // straight edges, mild distortion
  }
}

TEST(EdgeProjector, NormalsAreExactOnADistortedCameraToo) {
  // Each sample's pixel is its point projected, and its normal is perpendicular to the projected
  // edge there, curved by the lens (the straight edge's tangent from a small step along it).
  const model::Model box = load(synth::box_cao());
  using Lens = std::array<double, 5>;
  for (const Lens& lens : {Lens{0, 0, 0, 0, 0}, Lens{-0.3, 0.08, 0.001, -0.002, 0}}) {
    geometry::PinholeCamera cam = synth::default_camera();
    cam.dist = lens;
    const double k1 = lens[0];
    const geometry::SE3 T = geometry::look_at(0.45, 0.4, 0.5);
    EdgeProjector proj(box, 0.17);
    std::vector<EdgeSample> s(600);
    const std::size_t n = proj.sample(T, cam, 3.0, s);
    ASSERT_GT(n, 100u);
    int checked = 0;
    for (std::size_t i = 0; i + 1 < n; ++i) {
      EXPECT_LT((cam.project(T * s[i].p_obj) - s[i].px).norm(), 1e-9);
      if (s[i].piece != s[i + 1].piece) continue;
      const Eigen::Vector3d d = (s[i + 1].p_obj - s[i].p_obj).normalized() * 1e-6;  // along the straight edge
      const Eigen::Vector2d tan = (cam.project(T * (s[i].p_obj + d)) - cam.project(T * (s[i].p_obj - d))).normalized();
      EXPECT_LT(std::abs(tan.dot(s[i].normal)), 1e-6) << "k1 " << k1 << " sample " << i;
      ++checked;
    }
    EXPECT_GT(checked, 80);
  }
}

TEST(EdgeProjector, FlangeShowsCylinderLimbsAndHidesTheBackOfTheBottomRim) {
  const model::Model flange = load(synth::flange_cao());
  const geometry::PinholeCamera cam = synth::default_camera();
  const geometry::SE3 T = geometry::look_at(0.6, 0.4, 0.35);
  EdgeProjector proj(flange, 0.17);
  std::vector<EdgeSample> s(2000);
  const std::size_t n = proj.sample(T, cam, 3.0, s);
  ASSERT_GT(n, 100u);
  const Eigen::Vector3d cam_obj = T.inverse().translation();
  const Eigen::Vector2d towards(cam_obj.x(), cam_obj.y());
  int limb = 0, rim_back = 0, rim_front = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& p = s[i].p_obj;
    const double r = std::hypot(p.x(), p.y());
    if (std::abs(r - 0.05) > 1e-6) continue;
    if (p.z() > 0.005 && p.z() < 0.055) ++limb;  // on the side: a limb line
    if (std::abs(p.z()) < 1e-9) (Eigen::Vector2d(p.x(), p.y()).dot(towards) < -0.02 ? rim_back : rim_front)++;
  }
  EXPECT_GT(limb, 10);
  EXPECT_GT(rim_front, 5);
  EXPECT_EQ(rim_back, 0);  // behind the cylinder
}

// The projector tests a sample only against the front faces whose image boxes overlap its
// edge's; an exhaustive test against every face of the model agrees: no returned sample has a
// front face (other than the faces it lies on) between it and the camera. The ship section
// (plates, a frame and brackets) hides much of itself from most directions.
TEST(EdgeProjector, NoReturnedSampleIsBehindAnyFaceOfTheShipSection) {
  const model::Model section = load(synth::ship_section_cao());
  const geometry::PinholeCamera cam = synth::default_camera();
  EdgeProjector proj(section, 0.17);
  std::vector<EdgeSample> s(3000);
  std::vector<Eigen::Vector2d> poly;
  int hidden_by_faces = 0, checked = 0;
  for (int k = 0; k < 24; ++k) {
    const geometry::SE3 T = geometry::look_at(0.9, 0.27 * k, 0.2 + 0.05 * (k % 12));
    const std::size_t n = proj.sample(T, cam, 2.0, s);
    ASSERT_GT(n, 100u) << "pose " << k;
    const Eigen::Vector3d cam_obj = T.inverse().translation();
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d Xc = T * s[i].p_obj;
      const Eigen::Vector2d q(Xc.x() / Xc.z(), Xc.y() / Xc.z());
      ++checked;
      for (const model::Face& f : section.faces()) {
        const Eigen::Vector3d p0 = section.junctions()[f.loop[0]].p;
        if (f.normal.dot(cam_obj - p0) <= 0.0) continue;                 // a back face
        if (std::abs(f.normal.dot(s[i].p_obj - p0)) < 1e-7) continue;     // the sample lies on it
        const Eigen::Vector3d n_cam = T.rotation() * f.normal;
        const double den = n_cam.dot(Eigen::Vector3d(q.x(), q.y(), 1.0));
        if (std::abs(den) < 1e-12) continue;
        const double z = n_cam.dot(T * p0) / den;
        if (z <= 0.0 || z >= Xc.z() * (1.0 - 1e-3)) continue;  // behind the sample
        poly.clear();
        for (const model::Index j : f.loop) {
          const Eigen::Vector3d pc = T * section.junctions()[j].p;
          poly.emplace_back(pc.x() / pc.z(), pc.y() / pc.z());
        }
        if (geometry::inside_polygon(q, poly.data(), static_cast<std::uint32_t>(poly.size()))) {
          ++hidden_by_faces;
          break;
        }
      }
    }
  }
  EXPECT_GT(checked, 5000);
  EXPECT_EQ(hidden_by_faces, 0);
}

// The silhouette's object side (the colour test's inside): a few pixels along it the renderer's
// object mask is set and 3 and 10 px the other way it is not (the background: outlines against
// another part of the model, such as the plate behind the flange's cylinder or the ship's walls
// on their base plate, get no side), and creases have no side.
TEST(EdgeProjector, SilhouetteSamplesKnowWhichSideTheObjectIsOn) {
  const geometry::PinholeCamera cam = synth::default_camera();
  for (const int model : {0, 1, 2}) {
    const bool convex = model == 0;
    const model::Model m = load(model == 0 ? synth::box_cao() : model == 1 ? synth::flange_cao() : synth::ship_mockup_cao());
    for (int k = 0; k < 4; ++k) {
      const geometry::SE3 T = geometry::look_at(0.6 + (model == 2 ? 0.4 : 0.0), 0.4 + 1.3 * k, 0.35 + 0.1 * k);
      synth::RenderOptions ro;
      ro.textured_background = false;
      synth::Renderer r(cam, ro);
      synth::FrameInfo info;
      (void)r.render(m, T, 0, nullptr, &info);
      EdgeProjector proj(m, 0.17);
      std::vector<EdgeSample> s(2000);
      const std::size_t n = proj.sample(T, cam, 3.0, s);
      proj.mark_sides(std::span<EdgeSample>(s).first(n), 10.0);
      const auto object_at = [&](const Eigen::Vector2d& p) {
        const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
        return x >= 0 && y >= 0 && x < info.object_mask.cols && y < info.object_mask.rows && info.object_mask.at<std::uint8_t>(y, x) != 0;
      };
      int sided = 0, inside = 0, outline = 0, crease = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector2d& p = s[i].px;
        const Eigen::Vector2d& nm = s[i].normal;
        if (s[i].object_side == 0) {
          crease += object_at(p + 3.0 * nm) && object_at(p - 3.0 * nm) ? 1 : 0;
          continue;
        }
        ++sided;
        const double side = s[i].object_side;
        inside += object_at(p + 3.0 * side * nm) ? 1 : 0;
        outline += object_at(p + 3.0 * side * nm) && !object_at(p - 3.0 * side * nm) && !object_at(p - 10.0 * side * nm) ? 1 : 0;
      }
      EXPECT_GT(sided, 60) << "model " << model << " pose " << k;
      EXPECT_GE(inside, 0.95 * sided) << "model " << model << " pose " << k;
      EXPECT_GE(outline, 0.95 * sided) << "model " << model << " pose " << k;
      if (convex) {
        EXPECT_GT(crease, 20) << "pose " << k;
      }
    }
  }
}
