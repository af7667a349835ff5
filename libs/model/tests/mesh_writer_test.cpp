// v4r - robust model-based object tracking. MIT licence.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "v4r/model/cao_reader.hpp"
#include "v4r/model/mesh_writer.hpp"

namespace fs = std::filesystem;
using v4r::model::Cylinder;
using v4r::model::Index;
using v4r::model::MeshFormat;
using v4r::model::Model;
using v4r::model::ModelBuilder;
using v4r::model::TriangleMesh;

namespace {

Model load_data(const char* name) {
  auto m = v4r::model::load_cao(std::string(V4R_DATA_DIR) + "/" + name);
  EXPECT_TRUE(m) << m.error().to_string();
  return std::move(m).value();
}

fs::path temp_dir() {
  const fs::path d = fs::temp_directory_path() / ("v4r_mesh_writer_test_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Eigen::Vector3d tri_normal(const TriangleMesh& m, std::size_t t) {
  const auto& v = m.vertices;
  const auto& tr = m.triangles[t];
  return (v[tr[1]] - v[tr[0]]).cross(v[tr[2]] - v[tr[0]]);
}

double mesh_area(const TriangleMesh& m) {
  double a = 0.0;
  for (std::size_t t = 0; t < m.triangles.size(); ++t) a += 0.5 * tri_normal(m, t).norm();
  return a;
}

/// Signed volume of a closed, outward-wound mesh (divergence theorem).
double mesh_volume(const TriangleMesh& m) {
  double v = 0.0;
  for (const auto& t : m.triangles) v += m.vertices[t[0]].dot(m.vertices[t[1]].cross(m.vertices[t[2]])) / 6.0;
  return v;
}

}  // namespace

TEST(MeshWriter, BoxIsTwelveOutwardTrianglesFannedFromTheFirstCorner) {
  const Model box = load_data("box.cao");
  const TriangleMesh m = v4r::model::triangulate(box);
  ASSERT_EQ(m.vertices.size(), 8u);
  ASSERT_EQ(m.triangles.size(), 12u);
  // Each face (a convex quad) becomes the fan (l0, l1, l2), (l0, l2, l3).
  for (std::size_t f = 0; f < box.faces().size(); ++f) {
    const auto& loop = box.faces()[f].loop;
    EXPECT_EQ(m.triangles[2 * f], (std::array<Index, 3>{loop[0], loop[1], loop[2]}));
    EXPECT_EQ(m.triangles[2 * f + 1], (std::array<Index, 3>{loop[0], loop[2], loop[3]}));
    for (int k = 0; k < 2; ++k)
      EXPECT_GT(tri_normal(m, 2 * f + k).normalized().dot(box.faces()[f].normal), 1.0 - 1e-12);
  }
  EXPECT_NEAR(mesh_area(m), 2.0 * (0.2 * 0.15 + 0.2 * 0.1 + 0.15 * 0.1), 1e-12);
  EXPECT_NEAR(mesh_volume(m), 0.2 * 0.15 * 0.1, 1e-12);
}

TEST(MeshWriter, NonConvexFaceIsEarClippedWithoutLeavingThePolygon) {
  // An L-shaped face in the plane z = 0 (CCW seen from +z) and a U-shaped one.
  ModelBuilder b("shapes");
  const Eigen::Vector2d L[] = {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};
  const Eigen::Vector2d U[] = {{0, 0}, {3, 0}, {3, 2}, {2, 2}, {2, 1}, {1, 1}, {1, 2}, {0, 2}};
  std::vector<Index> l_loop, u_loop;
  for (const auto& p : L) l_loop.push_back(b.add_junction({p.x(), p.y(), 0.0}));
  for (const auto& p : U) u_loop.push_back(b.add_junction({p.x() + 5.0, p.y(), 1.0}));
  ASSERT_TRUE(b.add_face(l_loop));
  ASSERT_TRUE(b.add_face(u_loop));
  auto model = std::move(b).build();
  ASSERT_TRUE(model);
  const TriangleMesh m = v4r::model::triangulate(*model);
  ASSERT_EQ(m.triangles.size(), 4u + 6u);
  EXPECT_NEAR(mesh_area(m), 3.0 + 5.0, 1e-12);
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const Eigen::Vector3d n = tri_normal(m, t);
    EXPECT_GT(n.z(), 1e-9) << "triangle " << t << " is not counter-clockwise";
    // The centroid of every triangle lies inside its polygon (no triangle spans a notch).
    const Eigen::Vector3d c = (m.vertices[m.triangles[t][0]] + m.vertices[m.triangles[t][1]] + m.vertices[m.triangles[t][2]]) / 3.0;
    if (c.x() < 4.0) {
      EXPECT_FALSE(c.x() > 1.0 && c.y() > 1.0) << "triangle " << t << " covers the notch of the L";
    } else {
      EXPECT_FALSE(c.x() > 6.0 && c.x() < 7.0 && c.y() > 1.0) << "triangle " << t << " covers the notch of the U";
    }
  }
}

TEST(MeshWriter, CylinderIsClosedOutwardAndHasItsVerticesOnTheRadius) {
  ModelBuilder b("cyl");
  const Cylinder c{{0.01, -0.02, 0.03}, {0.04, 0.05, 0.13}, 0.04, {}};
  b.add_cylinder(c);
  auto model = std::move(b).build();
  ASSERT_TRUE(model);
  const int n = 48;
  const TriangleMesh m = v4r::model::triangulate(*model, n, true);
  ASSERT_EQ(m.vertices.size(), static_cast<std::size_t>(2 * n + 2));
  ASSERT_EQ(m.triangles.size(), static_cast<std::size_t>(4 * n));
  const Eigen::Vector3d axis = (c.p2 - c.p1).normalized();
  const double h = (c.p2 - c.p1).norm();
  for (std::size_t i = 0; i < 2u * n; ++i) {
    const Eigen::Vector3d d = m.vertices[i] - c.p1;
    EXPECT_NEAR((d - d.dot(axis) * axis).norm(), c.radius, 1e-12);
  }
  // Volume of the inscribed prism: n/2 r^2 sin(2 pi / n) h.
  const double prism = 0.5 * n * c.radius * c.radius * std::sin(2.0 * std::numbers::pi / n) * h;
  EXPECT_NEAR(mesh_volume(m), prism, 1e-12);
  // Side facets face away from the axis, caps along -axis / +axis.
  for (std::size_t t = 0; t < m.triangles.size(); ++t) {
    const Eigen::Vector3d nn = tri_normal(m, t).normalized();
    const Eigen::Vector3d cen = (m.vertices[m.triangles[t][0]] + m.vertices[m.triangles[t][1]] + m.vertices[m.triangles[t][2]]) / 3.0;
    const Eigen::Vector3d d = cen - c.p1;
    const double along = d.dot(axis);
    if (std::abs(along) < 1e-12) {
      EXPECT_LT(nn.dot(axis), -1.0 + 1e-12);
    } else if (std::abs(along - h) < 1e-12) {
      EXPECT_GT(nn.dot(axis), 1.0 - 1e-12);
    } else {
      EXPECT_GT(nn.dot((d - along * axis).normalized()), 0.99);
    }
  }
  // Without caps: only the side.
  EXPECT_EQ(v4r::model::triangulate(*model, n, false).triangles.size(), static_cast<std::size_t>(2 * n));
}

TEST(MeshWriter, FilesHaveTheDocumentedLayout) {
  const fs::path dir = temp_dir();
  const Model box = load_data("box.cao");
  v4r::model::MeshWriteOptions opt;
  opt.scale = 1000.0;  // millimetres
  ASSERT_TRUE(v4r::model::write_mesh(box, (dir / "box.obj").string(), opt));
  ASSERT_TRUE(v4r::model::write_mesh(box, (dir / "box.stl").string(), opt));
  ASSERT_TRUE(v4r::model::write_mesh(box, (dir / "box.ply").string(), opt));

  const std::string obj = slurp(dir / "box.obj");
  std::istringstream in(obj);
  int nv = 0, nf = 0;
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("v ", 0) == 0) {
      ++nv;
      double x, y, z;
      std::istringstream ls(line.substr(2));
      ls >> x >> y >> z;
      EXPECT_NEAR(std::abs(x), 100.0, 1e-9);  // 0.1 m written in millimetres
      EXPECT_NEAR(std::abs(y), 75.0, 1e-9);
      EXPECT_NEAR(std::abs(z), 50.0, 1e-9);
    }
    if (line.rfind("f ", 0) == 0) ++nf;
  }
  EXPECT_EQ(nv, 8);
  EXPECT_EQ(nf, 12);

  const std::string stl = slurp(dir / "box.stl");
  ASSERT_EQ(stl.size(), 84u + 50u * 12u);
  EXPECT_NE(stl.rfind("solid", 0), 0u) << "a binary STL must not start with 'solid'";
  std::uint32_t count = 0;
  std::memcpy(&count, stl.data() + 80, 4);
  EXPECT_EQ(count, 12u);
  float rec[12];
  std::memcpy(rec, stl.data() + 84, sizeof rec);  // first facet: normal, then three corners
  const Eigen::Vector3f a(rec[3], rec[4], rec[5]), b(rec[6], rec[7], rec[8]), c(rec[9], rec[10], rec[11]);
  EXPECT_GT((b - a).cross(c - a).normalized().dot(Eigen::Vector3f(rec[0], rec[1], rec[2])), 0.999f);

  const std::string ply = slurp(dir / "box.ply");
  EXPECT_EQ(ply.rfind("ply\nformat ascii 1.0\n", 0), 0u);
  EXPECT_NE(ply.find("element vertex 8\n"), std::string::npos);
  EXPECT_NE(ply.find("element face 12\n"), std::string::npos);

  auto bad = v4r::model::write_mesh(box, (dir / "box.xyz").string());
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().to_string().find("box.xyz"), std::string::npos);
  auto no_dir = v4r::model::write_mesh(box, (dir / "missing_dir" / "box.obj").string());
  EXPECT_FALSE(no_dir);
  fs::remove_all(dir);
}
