// v4r - robust model-based object tracking. MIT licence.
#include <cmath>

#include <gtest/gtest.h>

#include "v4r/model/model.hpp"

using v4r::model::Attributes;
using v4r::model::CircleArc;
using v4r::model::Cylinder;
using v4r::model::Index;
using v4r::model::kNone;
using v4r::model::Model;
using v4r::model::ModelBuilder;

namespace {

/// Regular tetrahedron-like solid: 4 junctions, 4 faces listed CCW from outside.
ModelBuilder tetrahedron() {
  ModelBuilder b("tetra");
  b.add_junction({0, 0, 0});
  b.add_junction({1, 0, 0});
  b.add_junction({0, 1, 0});
  b.add_junction({0, 0, 1});
  EXPECT_TRUE(b.add_face({0, 2, 1}));  // bottom, normal -z
  EXPECT_TRUE(b.add_face({0, 1, 3}));  // y = 0, normal -y
  EXPECT_TRUE(b.add_face({0, 3, 2}));  // x = 0, normal -x
  EXPECT_TRUE(b.add_face({1, 2, 3}));  // slanted, normal (1,1,1)/sqrt(3)
  return b;
}

}  // namespace

TEST(ModelBuilder, DuplicateLinesAreMergedInEitherDirection) {
  ModelBuilder b;
  b.add_junction({0, 0, 0});
  b.add_junction({1, 0, 0});
  b.add_junction({0, 1, 0});
  const Index l0 = b.add_line(0, 1);
  EXPECT_EQ(b.add_line(0, 1), l0);
  EXPECT_EQ(b.add_line(1, 0, Attributes{"late name", std::nullopt, 2}), l0);
  const Index l1 = b.add_line(1, 2, Attributes{"edge12", std::nullopt, 2});
  EXPECT_NE(l1, l0);
  EXPECT_EQ(b.add_line(2, 1, Attributes{"other", std::nullopt, 2}), l1);
  EXPECT_EQ(b.line_count(), 2u);
  auto m = std::move(b).build();
  ASSERT_TRUE(m) << m.error().to_string();
  EXPECT_EQ(m->lines()[l0].attr.name, "late name");  // an unnamed line takes the first name offered
  EXPECT_EQ(m->lines()[l1].attr.name, "edge12");     // a named line keeps its name
  EXPECT_EQ(m->junctions()[1].lines.size(), 2u);
  EXPECT_EQ(m->junctions()[0].lines.size(), 1u);
}

TEST(ModelBuilder, ClosedSolidHasEveryEdgeLinkedToTwoFaces) {
  auto m = tetrahedron().build();
  ASSERT_TRUE(m) << m.error().to_string();
  ASSERT_EQ(m->faces().size(), 4u);
  ASSERT_EQ(m->lines().size(), 6u);
  for (const auto& e : m->lines()) {
    EXPECT_NE(e.face_left, kNone);
    EXPECT_NE(e.face_right, kNone);
    EXPECT_NE(e.face_left, e.face_right);
    // Both faces contain both end points of the edge.
    for (Index f : {e.face_left, e.face_right}) {
      const auto& loop = m->faces()[f].loop;
      EXPECT_NE(std::find(loop.begin(), loop.end(), e.a), loop.end());
      EXPECT_NE(std::find(loop.begin(), loop.end(), e.b), loop.end());
    }
  }
  for (const auto& j : m->junctions()) EXPECT_EQ(j.lines.size(), 3u);
  // Outward normals by the right-hand rule on CCW loops.
  const Eigen::Vector3d expected[4] = {{0, 0, -1}, {0, -1, 0}, {-1, 0, 0}, Eigen::Vector3d(1, 1, 1).normalized()};
  for (int f = 0; f < 4; ++f) EXPECT_LT((m->faces()[f].normal - expected[f]).norm(), 1e-12) << "face " << f;
}

TEST(ModelBuilder, FaceEdgesReuseExistingLinesAndKeepTheirNames) {
  ModelBuilder b;
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 1, 0),
                                   Eigen::Vector3d(0, 1, 0)})
    b.add_junction(p);
  const Index named = b.add_line(2, 1, Attributes{"right", std::nullopt, 2});
  auto f = b.add_face({0, 1, 2, 3}, Attributes{"square", std::nullopt, 2});
  ASSERT_TRUE(f);
  EXPECT_EQ(b.line_count(), 4u);
  auto m = std::move(b).build();
  ASSERT_TRUE(m);
  EXPECT_EQ(m->lines()[named].attr.name, "right");
  EXPECT_EQ(m->lines()[named].face_left, *f);
  EXPECT_EQ(m->lines()[named].face_right, kNone);
  EXPECT_EQ(m->faces()[*f].attr.name, "square");
  EXPECT_LT((m->faces()[*f].normal - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
}

TEST(ModelBuilder, RejectsBadFaces) {
  ModelBuilder b;
  b.add_junction({0, 0, 0});
  b.add_junction({1, 0, 0});
  b.add_junction({2, 0, 0});
  b.add_junction({1, 1, 0.01});
  b.add_junction({0, 1, 0});
  auto two = b.add_face({0, 1});
  ASSERT_FALSE(two);
  EXPECT_NE(two.error().message.find("at least 3"), std::string::npos);
  auto range = b.add_face({0, 1, 9});
  ASSERT_FALSE(range);
  EXPECT_NE(range.error().message.find("point 9"), std::string::npos);
  auto flat = b.add_face({0, 1, 2});
  ASSERT_FALSE(flat);
  EXPECT_NE(flat.error().message.find("degenerate"), std::string::npos);
  auto bent = b.add_face({0, 1, 3, 4});
  ASSERT_FALSE(bent);
  EXPECT_NE(bent.error().message.find("not planar"), std::string::npos);
  EXPECT_TRUE(b.add_face({0, 1, 3, 4}, {}, 0.01));  // accepted with a looser tolerance
  EXPECT_EQ(b.line_count(), 4u);                    // failed faces added no edges
}

TEST(ModelBuilder, BoundingRadiusCoversJunctionsAndArcs) {
  ModelBuilder b;
  b.add_junction({0.3, 0.4, 0.0});  // |p| = 0.5
  b.add_junction({-0.1, 0.0, 0.0});
  b.add_line(0, 1);
  {
    auto m = ModelBuilder(b).build();
    ASSERT_TRUE(m);
    EXPECT_NEAR(m->bounding_radius(), 0.5, 1e-15);
  }
  CircleArc arc;
  arc.center = {0.0, 0.0, 0.6};
  arc.radius = 0.1;
  b.add_arc(arc);
  auto m = std::move(b).build();
  ASSERT_TRUE(m);
  EXPECT_NEAR(m->bounding_radius(), 0.7, 1e-15);
}

TEST(ModelBuilder, ArcAxesAreNormalisedAndOrthogonal) {
  ModelBuilder b;
  CircleArc arc;
  arc.normal = {0, 0, 2};
  arc.x_axis = {1, 0, 1};  // not in the plane: projected
  arc.radius = 0.05;
  b.add_arc(arc);
  CircleArc arc2;
  arc2.normal = {0, 3, 0};
  arc2.x_axis = {0, 1, 0};  // parallel to the normal: any orthogonal unit vector
  arc2.radius = 0.05;
  b.add_arc(arc2);
  auto m = std::move(b).build();
  ASSERT_TRUE(m);
  EXPECT_LT((m->arcs()[0].normal - Eigen::Vector3d::UnitZ()).norm(), 1e-15);
  EXPECT_LT((m->arcs()[0].x_axis - Eigen::Vector3d::UnitX()).norm(), 1e-15);
  EXPECT_NEAR(m->arcs()[1].x_axis.norm(), 1.0, 1e-15);
  EXPECT_NEAR(m->arcs()[1].x_axis.dot(m->arcs()[1].normal), 0.0, 1e-15);
}

TEST(ModelBuilder, CylinderAddsTwoRims) {
  ModelBuilder b;
  Cylinder c;
  c.p1 = {0.1, 0, 0};
  c.p2 = {0.1, 0, 0.3};
  c.radius = 0.02;
  c.attr.name = "can";
  EXPECT_EQ(b.add_cylinder(c), 0u);
  auto m = std::move(b).build();
  ASSERT_TRUE(m);
  ASSERT_EQ(m->cylinders().size(), 1u);
  ASSERT_EQ(m->arcs().size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const CircleArc& rim = m->arcs()[k];
    EXPECT_LT((rim.center - (k == 0 ? c.p1 : c.p2)).norm(), 1e-15);
    EXPECT_LT((rim.normal - Eigen::Vector3d::UnitZ()).norm(), 1e-15);
    EXPECT_NEAR(rim.x_axis.dot(rim.normal), 0.0, 1e-15);
    EXPECT_DOUBLE_EQ(rim.radius, 0.02);
    EXPECT_DOUBLE_EQ(rim.end - rim.start, 2 * M_PI);
    EXPECT_EQ(rim.attr.name, "can");
  }
  EXPECT_NEAR(m->bounding_radius(), std::hypot(0.1, 0.3) + 0.02, 1e-15);
}

TEST(ModelBuilder, BuildRejectsInvalidFeatures) {
  {
    ModelBuilder b;
    b.add_junction({0, 0, 0});
    b.add_junction({0, 0, 0});
    b.add_line(0, 1);
    auto m = std::move(b).build();
    ASSERT_FALSE(m);
    EXPECT_NE(m.error().message.find("zero length"), std::string::npos);
  }
  {
    ModelBuilder b;
    b.add_junction({0, std::nan(""), 0});
    auto m = std::move(b).build();
    ASSERT_FALSE(m);
    EXPECT_NE(m.error().message.find("non-finite"), std::string::npos);
  }
  {
    ModelBuilder b;
    b.add_junction({0, 0, 0});
    b.add_line(0, 5);
    auto m = std::move(b).build();
    ASSERT_FALSE(m);
    EXPECT_NE(m.error().message.find("does not exist"), std::string::npos);
  }
  {
    ModelBuilder b;
    CircleArc arc;
    arc.radius = 0.0;
    b.add_arc(arc);
    auto m = std::move(b).build();
    ASSERT_FALSE(m);
    EXPECT_NE(m.error().message.find("radius"), std::string::npos);
  }
}
