// v4r - robust model-based object tracking. MIT licence.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <unistd.h>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "v4r/model/cao_reader.hpp"
#include "v4r/model/mesh_reader.hpp"
#include "v4r/model/mesh_writer.hpp"
#include "v4r/model/model_colour.hpp"

namespace fs = std::filesystem;
using v4r::geometry::SE3;
using v4r::model::CircleArc;
using v4r::model::Cylinder;
using v4r::model::face_area;
using v4r::model::Index;
using v4r::model::kNone;
using v4r::model::load_mesh;
using v4r::model::MeshImportOptions;
using v4r::model::MeshImportStats;
using v4r::model::Model;
using v4r::model::ModelBuilder;
using v4r::model::TriangleMesh;
using Eigen::Vector3d;

namespace {

constexpr double kPi = std::numbers::pi;

std::string fmt_double(double x) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

Model load_data(const std::string& name) {
  auto m = v4r::model::load_cao(std::string(V4R_DATA_DIR) + "/" + name);
  EXPECT_TRUE(m) << m.error().to_string();
  return std::move(m).value();
}

/// A fresh directory per test process, removed at the end of the test that asks for it.
struct MeshTempDir {
  fs::path path = fs::temp_directory_path() / ("v4r_mesh_reader_test_" + std::to_string(::getpid()));
  MeshTempDir() { fs::create_directories(path); }
  ~MeshTempDir() { fs::remove_all(path); }
  [[nodiscard]] std::string file(const std::string& name) const { return (path / name).string(); }
};

double total_area(const Model& m) {
  double a = 0.0;
  for (const auto& f : m.faces()) a += face_area(m, f);
  return a;
}

Vector3d face_centroid(const Model& m, const v4r::model::Face& f) {
  Vector3d c = Vector3d::Zero();
  for (Index j : f.loop) c += m.junctions()[j].p;
  return c / static_cast<double>(f.loop.size());
}

/// Index of the line of `ref` with the same end points (either order) within tol, or kNone.
Index find_line(const Model& ref, const Vector3d& a, const Vector3d& b, double tol) {
  for (Index i = 0; i < ref.lines().size(); ++i) {
    const Vector3d ra = ref.line_point_a(i), rb = ref.line_point_b(i);
    if (((ra - a).norm() < tol && (rb - b).norm() < tol) || ((ra - b).norm() < tol && (rb - a).norm() < tol)) return i;
  }
  return kNone;
}

/// The unit normals of the faces bounded by a line (0, 1 or 2).
std::vector<Vector3d> line_face_normals(const Model& m, Index li) {
  std::vector<Vector3d> n;
  for (Index f : {m.lines()[li].face_left, m.lines()[li].face_right}) {
    if (f != kNone) n.push_back(m.faces()[f].normal);
  }
  return n;
}

/// Same line set (end points within tol, equal count), each line bounded by faces with the same
/// outward normals as in the reference.
void expect_same_lines(const Model& mesh, const Model& ref, double tol, const std::string& what) {
  EXPECT_EQ(mesh.lines().size(), ref.lines().size()) << what;
  std::vector<int> hits(ref.lines().size(), 0);
  for (Index i = 0; i < mesh.lines().size(); ++i) {
    const Index r = find_line(ref, mesh.line_point_a(i), mesh.line_point_b(i), tol);
    ASSERT_NE(r, kNone) << what << ": line " << i << " (" << mesh.line_point_a(i).transpose() << ") - ("
                        << mesh.line_point_b(i).transpose() << ") is not a model edge";
    ++hits[r];
    const auto nm = line_face_normals(mesh, i), nr = line_face_normals(ref, r);
    ASSERT_EQ(nm.size(), nr.size()) << what << ": line " << i;
    for (const Vector3d& n : nm) {
      bool paired = false;
      for (const Vector3d& o : nr) paired = paired || n.dot(o) > 1.0 - 1e-9;
      EXPECT_TRUE(paired) << what << ": line " << i << " bounds a face with normal " << n.transpose();
    }
    // face_left is the face whose loop runs from a to b.
    const auto& loop = mesh.faces()[mesh.lines()[i].face_left].loop;
    const Vector3d d = mesh.line_point_b(i) - mesh.line_point_a(i);
    const Vector3d n = mesh.faces()[mesh.lines()[i].face_left].normal;
    const Vector3d inward = n.cross(d);  // points into a face that runs a -> b counter-clockwise
    EXPECT_GT((face_centroid(mesh, mesh.faces()[mesh.lines()[i].face_left]) - mesh.line_point_a(i)).dot(inward), 0.0)
        << what << ": line " << i << " (loop of " << loop.size() << ")";
  }
  for (std::size_t r = 0; r < hits.size(); ++r) EXPECT_EQ(hits[r], 1) << what << ": model edge " << r;
}

/// Every face of `mesh` matches a face of `ref` with the same outward normal, centroid and area
/// (areas within 1e-6 relative: mesh files hold single-precision coordinates).
void expect_same_faces(const Model& mesh, const Model& ref, double tol, const std::string& what) {
  EXPECT_EQ(mesh.faces().size(), ref.faces().size()) << what;
  EXPECT_NEAR(total_area(mesh), total_area(ref), 1e-6 * total_area(ref)) << what;
  for (std::size_t i = 0; i < mesh.faces().size(); ++i) {
    const auto& f = mesh.faces()[i];
    bool found = false;
    for (const auto& g : ref.faces()) {
      found = found || (f.normal.dot(g.normal) > 1.0 - 1e-9 && (face_centroid(mesh, f) - face_centroid(ref, g)).norm() < tol &&
                        std::abs(face_area(mesh, f) - face_area(ref, g)) < 1e-6 * face_area(ref, g));
    }
    EXPECT_TRUE(found) << what << ": face " << i << " normal " << f.normal.transpose();
  }
}

/// A box of half sizes h whose faces are grids of quads (two triangles each) with n.x(), n.y(),
/// n.z() divisions along x, y, z, so that each box edge is split into several collinear pieces.
TriangleMesh subdivided_box(const Vector3d& h, const Eigen::Vector3i& n) {
  TriangleMesh m;
  const Vector3d o = -h;
  const Vector3d ax[3] = {Vector3d::UnitX() * 2 * h.x(), Vector3d::UnitY() * 2 * h.y(), Vector3d::UnitZ() * 2 * h.z()};
  // For each face: origin corner, u axis, v axis (u x v points out).
  const std::array<std::tuple<Vector3d, int, int>, 6> faces{{
      {o, 1, 0}, {o + ax[2], 0, 1},  // bottom, top
      {o, 0, 2}, {o + ax[1], 2, 0},  // front, back
      {o, 2, 1}, {o + ax[0], 1, 2},  // left, right
  }};
  for (const auto& [origin, iu, iv] : faces) {
    const int nu = n[iu], nv = n[iv];
    const auto base = static_cast<Index>(m.vertices.size());
    for (int j = 0; j <= nv; ++j) {
      for (int i = 0; i <= nu; ++i) m.vertices.push_back(origin + ax[iu] * (double(i) / nu) + ax[iv] * (double(j) / nv));
    }
    auto id = [&](int i, int j) { return static_cast<Index>(base + j * (nu + 1) + i); };
    for (int j = 0; j < nv; ++j) {
      for (int i = 0; i < nu; ++i) {
        m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
        m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
      }
    }
  }
  return m;
}

/// A plate [-0.15, 0.15] x [-0.1, 0.1] x [-0.02, 0] with a cylinder standing on its top face.
Model plate_with_cylinder(const Cylinder& cyl) {
  ModelBuilder b("plate_cylinder");
  const double x = 0.15, y = 0.1, z0 = -0.02, z1 = 0.0;
  for (double z : {z0, z1}) {
    b.add_junction({-x, -y, z});
    b.add_junction({x, -y, z});
    b.add_junction({x, y, z});
    b.add_junction({-x, y, z});
  }
  for (const std::vector<Index>& loop : std::vector<std::vector<Index>>{
           {0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {1, 2, 6, 5}, {3, 0, 4, 7}})
    EXPECT_TRUE(b.add_face(loop));
  b.add_cylinder(cyl);
  auto m = std::move(b).build();
  EXPECT_TRUE(m);
  return std::move(m).value();
}

/// The arc of `m` nearest to `centre`.
const CircleArc& nearest_arc(const Model& m, const Vector3d& centre) {
  std::size_t best = 0;
  for (std::size_t i = 1; i < m.arcs().size(); ++i)
    if ((m.arcs()[i].center - centre).norm() < (m.arcs()[best].center - centre).norm()) best = i;
  return m.arcs()[best];
}

}  // namespace

// ------------------------------------------------------------------------------------------

TEST(MeshReader, BuiltInModelsGiveTheirCaoEdgesAndFacesInEveryFormat) {
  MeshTempDir tmp;
  for (const std::string name : {"box", "ship_mockup"}) {
    const Model ref = load_data(name + ".cao");
    for (const std::string ext : {"obj", "stl", "ply"}) {
      const std::string path = tmp.file(name + "." + ext);
      ASSERT_TRUE(v4r::model::write_mesh(ref, path));
      MeshImportStats st;
      auto m = load_mesh(path, {}, &st);
      ASSERT_TRUE(m) << m.error().to_string();
      const std::string what = name + "." + ext;
      expect_same_lines(*m, ref, 1e-6, what);
      expect_same_faces(*m, ref, 1e-6, what);
      EXPECT_TRUE(m->arcs().empty()) << what;
      EXPECT_EQ(st.flipped_triangles, 0u) << what;
      EXPECT_EQ(m->name(), name);
      EXPECT_NEAR(m->bounding_radius(), ref.bounding_radius(), 1e-6) << what;
      std::printf("[ mesh     ] %-16s %4zu triangles, %3zu welded vertices -> %2zu lines, %2zu faces; read %.2f ms, "
                  "extract %.2f ms\n",
                  what.c_str(), st.file_triangles, st.welded_vertices, m->lines().size(), m->faces().size(), st.read_ms,
                  st.extract_ms);
    }
  }
}

TEST(MeshReader, MillimetreFileWithTransformIsPlacedInTheObjectFrame) {
  MeshTempDir tmp;
  const Model ref = load_data("ship_mockup.cao");
  // The file frame is rotated and shifted with respect to the object frame, and in millimetres.
  const SE3 T_obj_file = SE3::from_rvec(Vector3d(0.03, -0.2, 0.1), Vector3d(0.3, -0.5, 1.1));
  TriangleMesh mesh = v4r::model::triangulate(ref);
  for (Vector3d& p : mesh.vertices) p = 1000.0 * (T_obj_file.inverse() * p);
  for (const std::string ext : {"obj", "stl"}) {
    const std::string path = tmp.file("ship_mm." + ext);
    ASSERT_TRUE(v4r::model::write_mesh(mesh, path));
    MeshImportOptions opt;
    opt.scale = 0.001;
    opt.T_obj_file = T_obj_file;
    auto m = load_mesh(path, opt);
    ASSERT_TRUE(m) << m.error().to_string();
    expect_same_lines(*m, ref, 1e-6, "ship_mm." + ext);
    expect_same_faces(*m, ref, 1e-6, "ship_mm." + ext);
    // Without the transform the model is elsewhere: the check is not vacuous.
    auto raw = load_mesh(path, MeshImportOptions{.scale = 0.001});
    ASSERT_TRUE(raw);
    EXPECT_EQ(find_line(ref, raw->line_point_a(0), raw->line_point_b(0), 1e-3), kNone);
  }
  // The writer's own transform option gives the same file frame.
  v4r::model::MeshWriteOptions wopt;
  wopt.scale = 1000.0;
  wopt.T_file_obj = T_obj_file.inverse();
  ASSERT_TRUE(v4r::model::write_mesh(ref, tmp.file("ship_mm.ply"), wopt));
  auto m = load_mesh(tmp.file("ship_mm.ply"), MeshImportOptions{.scale = 0.001, .T_obj_file = T_obj_file});
  ASSERT_TRUE(m) << m.error().to_string();
  expect_same_lines(*m, ref, 1e-6, "ship_mm.ply");
}

TEST(MeshReader, TessellatedCylinderOnPlateGivesTwoCirclesAndNoSideLines) {
  MeshTempDir tmp;
  const Cylinder cyl{{0.05, 0.02, 0.0}, {0.05, 0.02, 0.1}, 0.04, {}};
  const Model ref = plate_with_cylinder(cyl);
  for (const bool caps : {true, false}) {
    for (const std::string ext : {"obj", "stl", "ply"}) {
      const std::string what = std::string(caps ? "capped" : "open") + " cylinder ." + ext;
      const std::string path = tmp.file("cyl." + ext);
      ASSERT_TRUE(v4r::model::write_mesh(ref, path, {.cylinder_segments = 48, .cylinder_caps = caps}));
      MeshImportStats st;
      auto m = load_mesh(path, {}, &st);
      ASSERT_TRUE(m) << m.error().to_string();
      ASSERT_EQ(m->arcs().size(), 2u) << what;
      // Only the plate's 12 edges: nothing on the cylinder side (facets 7.5 deg apart).
      ModelBuilder plate_only("plate");
      for (const auto& j : ref.junctions()) plate_only.add_junction(j.p);
      for (const auto& f : ref.faces()) ASSERT_TRUE(plate_only.add_face(f.loop));
      auto plate = std::move(plate_only).build();
      ASSERT_TRUE(plate);
      expect_same_lines(*m, *plate, 1e-6, what);
      const Vector3d axis = (cyl.p2 - cyl.p1).normalized();
      for (const auto& [centre, sign] : {std::pair{cyl.p1, -1.0}, std::pair{cyl.p2, 1.0}}) {
        const CircleArc& a = nearest_arc(*m, centre);
        EXPECT_LT((a.center - centre).norm(), 1e-3 * cyl.radius) << what;
        EXPECT_NEAR(a.radius, cyl.radius, 1e-3 * cyl.radius) << what;
        // The normal points away from the cylinder side: the cap's outward normal.
        EXPECT_GT(sign * a.normal.dot(axis), 1.0 - 1e-3) << what;
        EXPECT_DOUBLE_EQ(a.start, 0.0);
        EXPECT_DOUBLE_EQ(a.end, 2.0 * kPi);
        EXPECT_NEAR(a.x_axis.dot(a.normal), 0.0, 1e-9);
        if (caps) {
          ASSERT_NE(a.face, kNone) << what;
          EXPECT_GT(m->faces()[a.face].normal.dot(a.normal), 1.0 - 1e-9) << what;
          EXPECT_EQ(m->faces()[a.face].loop.size(), 48u) << what;
        } else {
          EXPECT_EQ(a.face, kNone) << what;
        }
      }
      // Faces: 6 plate faces, 48 side facets (each a merged quad), 2 caps.
      EXPECT_EQ(m->faces().size(), 6u + 48u + (caps ? 2u : 0u)) << what;
      std::printf("[ mesh     ] %-22s %4zu triangles -> %zu lines, %zu circles, %zu faces; read %.2f ms, extract %.2f ms\n",
                  what.c_str(), st.file_triangles, m->lines().size(), m->arcs().size(), m->faces().size(), st.read_ms,
                  st.extract_ms);
    }
  }
}

TEST(MeshReader, TiltedCylinderCirclesFollowTheAxis) {
  MeshTempDir tmp;
  const Vector3d p1(0.01, -0.03, 0.02);
  const Vector3d axis = Vector3d(0.3, -0.4, 0.866).normalized();
  ModelBuilder b("tilted");
  b.add_cylinder({p1, p1 + 0.07 * axis, 0.025, {}});
  auto ref = std::move(b).build();
  ASSERT_TRUE(ref);
  ASSERT_TRUE(v4r::model::write_mesh(*ref, tmp.file("tilted.stl"), {.cylinder_segments = 64}));
  auto m = load_mesh(tmp.file("tilted.stl"));
  ASSERT_TRUE(m) << m.error().to_string();
  EXPECT_TRUE(m->lines().empty());
  ASSERT_EQ(m->arcs().size(), 2u);
  for (const auto& [centre, sign] : {std::pair{p1, -1.0}, std::pair{Vector3d(p1 + 0.07 * axis), 1.0}}) {
    const CircleArc& a = nearest_arc(*m, centre);
    EXPECT_LT((a.center - centre).norm(), 1e-3 * 0.025);
    EXPECT_NEAR(a.radius, 0.025, 1e-3 * 0.025);
    EXPECT_GT(sign * a.normal.dot(axis), 1.0 - 1e-3);
  }
}

TEST(MeshReader, EdgeSplitIntoCollinearPiecesIsOneLine) {
  // Every box edge is split into 3..5 pieces by the face grids; float STL coordinates from
  // different faces meet within the weld tolerance.
  MeshTempDir tmp;
  const Model ref = load_data("box.cao");
  const TriangleMesh grid = subdivided_box(Vector3d(0.1, 0.075, 0.05), Eigen::Vector3i(5, 4, 3));
  for (const std::string ext : {"stl", "obj"}) {
    ASSERT_TRUE(v4r::model::write_mesh(grid, tmp.file("grid_box." + ext)));
    MeshImportStats st;
    auto m = load_mesh(tmp.file("grid_box." + ext), {}, &st);
    ASSERT_TRUE(m) << m.error().to_string();
    EXPECT_GT(st.sharp_pieces, 12u);  // the pieces before the merge
    expect_same_lines(*m, ref, 1e-6, "grid_box." + ext);
    // Coplanar triangles merge into 6 quads (the vertices on straight boundary runs dropped).
    expect_same_faces(*m, ref, 1e-6, "grid_box." + ext);
    for (const auto& f : m->faces()) EXPECT_EQ(f.loop.size(), 4u);
    EXPECT_EQ(m->junctions().size(), 8u);
  }
  // Without coplanar merging every triangle is a face, and the merged line takes its dominant
  // faces from the pieces.
  auto tri = v4r::model::mesh_to_model(grid, "grid", {.merge_coplanar = false});
  ASSERT_TRUE(tri) << tri.error().to_string();
  EXPECT_EQ(tri->faces().size(), grid.triangles.size());
  EXPECT_EQ(tri->lines().size(), 12u);
  for (Index i = 0; i < tri->lines().size(); ++i) {
    const auto& e = tri->lines()[i];
    ASSERT_NE(e.face_left, kNone);
    ASSERT_NE(e.face_right, kNone);
    EXPECT_LT(tri->faces()[e.face_left].normal.dot(tri->faces()[e.face_right].normal), 0.5);
    EXPECT_NE(find_line(ref, tri->line_point_a(i), tri->line_point_b(i), 1e-9), kNone);
  }
}

TEST(MeshReader, PlateWithHoleGivesRimCirclesAndTriangleFacesAroundTheHole) {
  // A square plate [-0.1, 0.1]^2 x [0, 0.02] with a through hole of radius 0.03: the top and
  // bottom rings are triangulated between 32 points on the hole and 32 points on the square (the
  // square's corners among them), so the outer edges come in collinear pieces too.
  const int n = 32;
  const double r = 0.03, s = 0.1, t = 0.02;
  TriangleMesh m;
  auto square_point = [&](double th) {
    const Vector3d d(std::cos(th), std::sin(th), 0.0);
    return Vector3d(d * (s / std::max(std::abs(d.x()), std::abs(d.y()))));
  };
  for (double z : {0.0, t}) {
    for (int k = 0; k < n; ++k) {
      const double th = 2.0 * kPi * k / n;
      m.vertices.push_back(Vector3d(r * std::cos(th), r * std::sin(th), z));  // hole
      m.vertices.push_back(square_point(th) + Vector3d(0, 0, z));             // square
    }
  }
  auto hole = [&](int k, int level) { return static_cast<Index>(level * 2 * n + 2 * (k % n)); };
  auto outer = [&](int k, int level) { return static_cast<Index>(level * 2 * n + 2 * (k % n) + 1); };
  for (int k = 0; k < n; ++k) {
    // top ring (normal +z), bottom ring (normal -z)
    m.triangles.push_back({hole(k, 1), outer(k, 1), outer(k + 1, 1)});
    m.triangles.push_back({hole(k, 1), outer(k + 1, 1), hole(k + 1, 1)});
    m.triangles.push_back({hole(k, 0), outer(k + 1, 0), outer(k, 0)});
    m.triangles.push_back({hole(k, 0), hole(k + 1, 0), outer(k + 1, 0)});
    // outer wall (normal outward), hole wall (normal towards the axis)
    m.triangles.push_back({outer(k, 0), outer(k + 1, 0), outer(k + 1, 1)});
    m.triangles.push_back({outer(k, 0), outer(k + 1, 1), outer(k, 1)});
    m.triangles.push_back({hole(k, 0), hole(k + 1, 1), hole(k + 1, 0)});
    m.triangles.push_back({hole(k, 0), hole(k, 1), hole(k + 1, 1)});
  }
  MeshImportStats st;
  auto model = v4r::model::mesh_to_model(m, "plate_hole", {}, &st);
  ASSERT_TRUE(model) << model.error().to_string();
  EXPECT_EQ(st.flipped_triangles, 0u);
  // 12 outer edges (each merged from 8 pieces), 2 rims.
  ModelBuilder b("ref");
  for (double z : {0.0, t}) {
    b.add_junction({-s, -s, z});
    b.add_junction({s, -s, z});
    b.add_junction({s, s, z});
    b.add_junction({-s, s, z});
  }
  for (const std::vector<Index>& loop : std::vector<std::vector<Index>>{
           {0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {1, 2, 6, 5}, {3, 0, 4, 7}})
    ASSERT_TRUE(b.add_face(loop));
  auto ref = std::move(b).build();
  ASSERT_TRUE(ref);
  expect_same_lines(*model, *ref, 1e-9, "plate_hole");
  ASSERT_EQ(model->arcs().size(), 2u);
  for (const auto& [z, sign] : {std::pair{0.0, -1.0}, std::pair{t, 1.0}}) {
    const CircleArc& a = nearest_arc(*model, Vector3d(0, 0, z));
    EXPECT_LT((a.center - Vector3d(0, 0, z)).norm(), 1e-9);
    EXPECT_NEAR(a.radius, r, 1e-9);
    EXPECT_GT(sign * a.normal.z(), 1.0 - 1e-9);  // the ring's outward normal
    ASSERT_NE(a.face, kNone);                    // a triangle of the ring
    EXPECT_GT(model->faces()[a.face].normal.dot(a.normal), 1.0 - 1e-9);
  }
  // Rings with a hole are not simple polygons: their triangles stay faces. The walls merge.
  EXPECT_EQ(model->faces().size(), 2u * 2 * n + 4u + n);
  EXPECT_NEAR(total_area(*model), 2 * (4 * s * s - 0.5 * n * r * r * std::sin(2 * kPi / n)) + 4 * 2 * s * t +
                                      n * 2 * r * std::sin(kPi / n) * t,
              1e-12);
}

TEST(MeshReader, RoundedRectangleGivesQuarterArcsAndStraightSides) {
  // A slab whose outline is a rectangle with rounded corners (radius 0.02, 12 pieces per quarter):
  // the outline is one closed chain of sharp pieces on top and one on the bottom; each must
  // split into 4 straight sides and 4 quarter arcs.
  const double a = 0.08, b = 0.05, rc = 0.02, h = 0.01;
  const int q = 12;
  std::vector<Vector3d> outline;
  const Vector3d corners[4] = {{a - rc, b - rc, 0}, {-(a - rc), b - rc, 0}, {-(a - rc), -(b - rc), 0}, {a - rc, -(b - rc), 0}};
  for (int c = 0; c < 4; ++c) {
    for (int k = 0; k <= q; ++k) {
      const double th = kPi / 2 * c + kPi / 2 * k / q;
      outline.push_back(corners[c] + rc * Vector3d(std::cos(th), std::sin(th), 0));
    }
  }
  const auto n = static_cast<Index>(outline.size());
  TriangleMesh m;
  for (double z : {0.0, h}) {
    for (const Vector3d& p : outline) m.vertices.push_back(p + Vector3d(0, 0, z));
  }
  m.vertices.push_back({0, 0, 0});
  m.vertices.push_back({0, 0, h});
  const Index c0 = 2 * n, c1 = 2 * n + 1;
  for (Index k = 0; k < n; ++k) {
    const Index k1 = (k + 1) % n;
    m.triangles.push_back({c1, n + k, n + k1});  // top
    m.triangles.push_back({c0, k1, k});          // bottom
    m.triangles.push_back({k, k1, n + k1});      // side
    m.triangles.push_back({k, n + k1, n + k});
  }
  auto model = v4r::model::mesh_to_model(m, "rounded", {});
  ASSERT_TRUE(model) << model.error().to_string();
  EXPECT_EQ(model->lines().size(), 8u + 0u);  // 4 sides on top, 4 on the bottom; no vertical edges
  ASSERT_EQ(model->arcs().size(), 8u);
  for (const auto& arc : model->arcs()) {
    EXPECT_NEAR(arc.radius, rc, 1e-9);
    EXPECT_NEAR(arc.end - arc.start, kPi / 2, 1e-9);
    bool at_corner = false;
    for (const Vector3d& c : corners) {
      at_corner = at_corner || (arc.center - c - Vector3d(0, 0, arc.center.z())).norm() < 1e-9;
    }
    EXPECT_TRUE(at_corner) << arc.center.transpose();
    // Arc end points are the tangent points of the straight sides.
    const Vector3d y_axis = arc.normal.cross(arc.x_axis);
    const Vector3d p0 = arc.center + arc.radius * arc.x_axis;
    const Vector3d p1 = arc.center + arc.radius * (std::cos(arc.end) * arc.x_axis + std::sin(arc.end) * y_axis);
    for (const Vector3d& p : {p0, p1}) {
      bool on_line_end = false;
      for (Index i = 0; i < model->lines().size(); ++i)
        on_line_end = on_line_end || (model->line_point_a(i) - p).norm() < 1e-9 || (model->line_point_b(i) - p).norm() < 1e-9;
      EXPECT_TRUE(on_line_end) << p.transpose();
    }
  }
  for (Index i = 0; i < model->lines().size(); ++i) {
    const double len = (model->line_point_b(i) - model->line_point_a(i)).norm();
    EXPECT_TRUE(std::abs(len - 2 * (a - rc)) < 1e-9 || std::abs(len - 2 * (b - rc)) < 1e-9) << len;
  }
  // With circle detection off the arcs stay as short lines.
  auto no_circles = v4r::model::mesh_to_model(m, "rounded", {.detect_circles = false});
  ASSERT_TRUE(no_circles);
  EXPECT_TRUE(no_circles->arcs().empty());
  EXPECT_EQ(no_circles->lines().size(), 2u * (4 + 4 * q));
}

TEST(MeshReader, HalfDiscGivesOneArcAndItsDiameterPerOutline) {
  // An extruded half disc (radius 0.05, 24 pieces on the arc): every outline vertex but the two
  // corners turns by the same 7.5 deg, so the loop is cut at its straightest vertex, inside the
  // arc; the arc must still come out whole.
  const double r = 0.05, h = 0.02;
  const int q = 24;
  TriangleMesh m;
  for (double z : {0.0, h}) {
    for (int k = 0; k <= q; ++k) {
      const double th = kPi * k / q;
      m.vertices.push_back({r * std::cos(th), r * std::sin(th), z});
    }
  }
  const Index n = q + 1;
  for (Index k = 0; k < n; ++k) {
    const Index k1 = (k + 1) % n;  // k = q closes the outline along the diameter
    m.triangles.push_back({k, k1, n + k1});
    m.triangles.push_back({k, n + k1, n + k});
    if (k >= 1 && k + 1 < n) {
      m.triangles.push_back({0, k + 1, k});          // bottom fan
      m.triangles.push_back({n, n + k, n + k + 1});  // top fan
    }
  }
  auto model = v4r::model::mesh_to_model(m, "half_disc");
  ASSERT_TRUE(model) << model.error().to_string();
  ASSERT_EQ(model->arcs().size(), 2u);
  for (const auto& arc : model->arcs()) {
    EXPECT_NEAR(arc.radius, r, 1e-12);
    EXPECT_NEAR(arc.center.head<2>().norm(), 0.0, 1e-12);
    EXPECT_NEAR(arc.end - arc.start, kPi, 1e-9);
    // It runs counter-clockwise about its normal from one corner (+-r, 0) to the other, through y > 0.
    const Vector3d y_axis = arc.normal.cross(arc.x_axis);
    const Vector3d p0 = arc.center + r * arc.x_axis;
    const Vector3d p1 = arc.center + r * (std::cos(arc.end) * arc.x_axis + std::sin(arc.end) * y_axis);
    const Vector3d mid = arc.center + r * (std::cos(0.5 * arc.end) * arc.x_axis + std::sin(0.5 * arc.end) * y_axis);
    EXPECT_NEAR(std::abs(p0.x()), r, 1e-12);
    EXPECT_NEAR(p0.y(), 0.0, 1e-12);
    EXPECT_NEAR(p1.x(), -p0.x(), 1e-12);
    EXPECT_NEAR(p1.y(), 0.0, 1e-12);
    EXPECT_NEAR(mid.y(), r, 1e-12);
    ASSERT_NE(arc.face, kNone);
    EXPECT_GT(std::abs(arc.normal.z()), 1.0 - 1e-12);
    EXPECT_GT(model->faces()[arc.face].normal.dot(arc.normal), 1.0 - 1e-12);
  }
  // Two diameters and two vertical edges at the corners.
  EXPECT_EQ(model->lines().size(), 4u);
  for (Index i = 0; i < model->lines().size(); ++i) {
    const double len = (model->line_point_b(i) - model->line_point_a(i)).norm();
    EXPECT_TRUE(std::abs(len - 2 * r) < 1e-12 || std::abs(len - h) < 1e-12) << len;
  }
}

TEST(MeshReader, AllMeshesAndNodeInstancesArePlacedAndWelded) {
  MeshTempDir tmp;
  const Model ref = load_data("box.cao");
  const TriangleMesh box = v4r::model::triangulate(ref);
  // OBJ with the box split into two objects (two assimp meshes): the weld joins them.
  {
    std::string obj;
    for (const Vector3d& p : box.vertices) obj += "v " + std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) + "\n";
    for (std::size_t t = 0; t < box.triangles.size(); ++t) {
      if (t == 0) obj += "o first_half\n";
      if (t == 6) obj += "o second_half\n";
      obj += "f " + std::to_string(box.triangles[t][0] + 1) + " " + std::to_string(box.triangles[t][1] + 1) + " " +
             std::to_string(box.triangles[t][2] + 1) + "\n";
    }
    std::ofstream(tmp.file("two_objects.obj")) << obj;
    auto m = load_mesh(tmp.file("two_objects.obj"));
    ASSERT_TRUE(m) << m.error().to_string();
    expect_same_lines(*m, ref, 1e-6, "two_objects.obj");
    expect_same_faces(*m, ref, 1e-6, "two_objects.obj");
  }
  // Collada: one geometry instanced by two nodes, one of them nested under a transformed parent.
  const SE3 T_a = SE3::from_rvec(Vector3d(0.5, 0, 0), Vector3d::Zero());
  const SE3 T_parent = SE3::from_rvec(Vector3d(0, 0.1, 0.2), Vector3d(0, 0, kPi / 2));
  const SE3 T_child = SE3::from_rvec(Vector3d(-0.3, 0, 0), Vector3d(0.4, 0, 0));
  auto matrix = [](const SE3& T) {
    std::string s;
    const Eigen::Matrix4d M = T.matrix();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) s += fmt_double(M(r, c)) + " ";
    return s;
  };
  std::string pos, idx;
  for (const Vector3d& p : box.vertices) pos += fmt_double(p.x()) + " " + fmt_double(p.y()) + " " + fmt_double(p.z()) + " ";
  for (const auto& t : box.triangles) idx += std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + " ";
  const std::string dae =
      "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
      "<COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">\n"
      "<asset><unit name=\"meter\" meter=\"1\"/><up_axis>Y_UP</up_axis></asset>\n"
      "<library_geometries><geometry id=\"box\"><mesh>\n"
      "<source id=\"box-pos\"><float_array id=\"box-pos-array\" count=\"24\">" + pos + "</float_array>\n"
      "<technique_common><accessor source=\"#box-pos-array\" count=\"8\" stride=\"3\">"
      "<param name=\"X\" type=\"float\"/><param name=\"Y\" type=\"float\"/><param name=\"Z\" type=\"float\"/>"
      "</accessor></technique_common></source>\n"
      "<vertices id=\"box-vtx\"><input semantic=\"POSITION\" source=\"#box-pos\"/></vertices>\n"
      "<triangles count=\"12\"><input semantic=\"VERTEX\" source=\"#box-vtx\" offset=\"0\"/><p>" + idx + "</p></triangles>\n"
      "</mesh></geometry></library_geometries>\n"
      "<library_visual_scenes><visual_scene id=\"scene\">\n"
      "<node id=\"a\"><matrix>" + matrix(T_a) + "</matrix><instance_geometry url=\"#box\"/></node>\n"
      "<node id=\"parent\"><matrix>" + matrix(T_parent) + "</matrix>\n"
      "  <node id=\"child\"><matrix>" + matrix(T_child) + "</matrix><instance_geometry url=\"#box\"/></node></node>\n"
      "</visual_scene></library_visual_scenes>\n"
      "<scene><instance_visual_scene url=\"#scene\"/></scene>\n"
      "</COLLADA>\n";
  std::ofstream(tmp.file("instances.dae")) << dae;
  auto m = load_mesh(tmp.file("instances.dae"));
  ASSERT_TRUE(m) << m.error().to_string();
  // Reference: the two placed boxes.
  ModelBuilder b("two_boxes");
  for (const SE3& T : {T_a, SE3(T_parent * T_child)}) {
    const auto base = static_cast<Index>(b.junction_count());
    for (const auto& j : ref.junctions()) b.add_junction(T * j.p);
    for (const auto& f : ref.faces()) {
      std::vector<Index> loop;
      for (Index j : f.loop) loop.push_back(base + j);
      ASSERT_TRUE(b.add_face(loop));
    }
  }
  auto two = std::move(b).build();
  ASSERT_TRUE(two);
  expect_same_lines(*m, *two, 1e-6, "instances.dae");
  expect_same_faces(*m, *two, 1e-6, "instances.dae");
}

TEST(MeshReader, OpenSheetHasBoundaryLinesWithOneFace) {
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {0.1, 0, 0}, {0.1, 0.05, 0}, {0, 0.05, 0}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  auto model = v4r::model::mesh_to_model(m, "sheet");
  ASSERT_TRUE(model) << model.error().to_string();
  ASSERT_EQ(model->faces().size(), 1u);
  EXPECT_GT(model->faces()[0].normal.z(), 1.0 - 1e-12);
  ASSERT_EQ(model->lines().size(), 4u);
  for (const auto& e : model->lines()) {
    EXPECT_EQ(e.face_left, 0u);
    EXPECT_EQ(e.face_right, kNone);
  }
  // A second panel hinged on the edge x = 0.1. Folded by 30 deg (above sharp_angle = 20 deg) the
  // hinge is an edge; by 10 deg it is not, but the outline still bends there (6 lines); by 0.5 deg
  // (below collinear_angle) the outline pieces on either side of the hinge merge (4 lines).
  for (const auto& [deg, lines] : {std::pair{0.5, 4u}, std::pair{10.0, 6u}, std::pair{30.0, 7u}}) {
    TriangleMesh f = m;
    const double th = deg * kPi / 180.0;
    f.vertices.push_back({0.1 + 0.05 * std::cos(th), 0, 0.05 * std::sin(th)});
    f.vertices.push_back({0.1 + 0.05 * std::cos(th), 0.05, 0.05 * std::sin(th)});
    f.triangles.push_back({1, 4, 5});
    f.triangles.push_back({1, 5, 2});
    auto fm = v4r::model::mesh_to_model(f, "fold");
    ASSERT_TRUE(fm) << fm.error().to_string();
    EXPECT_EQ(fm->lines().size(), lines) << deg << " deg";
    EXPECT_EQ(fm->faces().size(), 2u) << deg << " deg";
  }
}

TEST(MeshReader, WindingIsMadeConsistentAndOutward) {
  TriangleMesh m = v4r::model::triangulate(load_data("box.cao"));
  // Turn the whole box inside out, then flip a few triangles back.
  for (auto& t : m.triangles) std::swap(t[1], t[2]);
  for (std::size_t t : {0u, 5u, 7u}) std::swap(m.triangles[t][1], m.triangles[t][2]);
  MeshImportStats st;
  auto model = v4r::model::mesh_to_model(m, "inside_out", {}, &st);
  ASSERT_TRUE(model) << model.error().to_string();
  EXPECT_EQ(st.flipped_triangles, 9u);
  const Model ref = load_data("box.cao");
  expect_same_faces(*model, ref, 1e-9, "inside_out");
  expect_same_lines(*model, ref, 1e-9, "inside_out");
}

TEST(MeshReader, MalformedInputsAreErrorsNamingTheFile) {
  MeshTempDir tmp;
  auto expect_error = [](const std::string& path, const std::string& fragment) {
    auto m = load_mesh(path);
    ASSERT_FALSE(m) << path;
    const std::string s = m.error().to_string();
    EXPECT_NE(s.find(path), std::string::npos) << s;
    EXPECT_NE(s.find(fragment), std::string::npos) << s;
  };
  expect_error(tmp.file("missing.obj"), "no such file");
  expect_error(tmp.path.string(), "directory");
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(tmp.file(name), std::ios::binary) << text;
    return tmp.file(name);
  };
  expect_error(write("empty.obj", ""), "cannot read the mesh");
  expect_error(write("empty.stl", ""), "cannot read the mesh");
  std::mt19937 rng(7);
  std::string junk(3000, '\0');
  for (char& c : junk) c = static_cast<char>(rng() & 0xFF);
  expect_error(write("garbage.stl", junk), "cannot read the mesh");
  expect_error(write("garbage.ply", "ply\nformat nonsense\n" + junk), "cannot read the mesh");
  expect_error(write("garbage.xyz123", junk), "cannot read the mesh");
  expect_error(write("text.obj", "this is not a mesh\n"), "no triangles");
  expect_error(write("lines.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\n"), "no triangles");
  expect_error(write("nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), "non-finite");
  expect_error(write("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"), "degenerate");
  // A bad option is an error too, not a crash.
  auto bad = load_mesh(write("ok.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), {.scale = 0.0});
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().to_string().find("scale"), std::string::npos);
  EXPECT_TRUE(load_mesh(tmp.file("ok.obj")));
}

TEST(MeshReader, LargeMeshLoadsQuickly) {
  // 2 x 2 x (120 x 90 + 120 x 60 + 90 x 60) = 93600 triangles: a finely meshed box, written as an
  // STL triangle soup that the weld must stitch.
  MeshTempDir tmp;
  const Eigen::Vector3i n(120, 90, 60);
  const TriangleMesh grid = subdivided_box(Vector3d(0.1, 0.075, 0.05), n);
  ASSERT_TRUE(v4r::model::write_mesh(grid, tmp.file("fine_box.stl")));
  MeshImportStats st;
  const auto t0 = std::chrono::steady_clock::now();
  auto m = load_mesh(tmp.file("fine_box.stl"), {}, &st);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(m) << m.error().to_string();
  EXPECT_EQ(st.file_triangles, grid.triangles.size());
  const std::size_t surface_vertices = static_cast<std::size_t>((n.x() + 1) * (n.y() + 1) * (n.z() + 1) -
                                                                (n.x() - 1) * (n.y() - 1) * (n.z() - 1));
  EXPECT_EQ(st.welded_vertices, surface_vertices);
  EXPECT_EQ(st.sharp_pieces, static_cast<std::size_t>(4 * (n.x() + n.y() + n.z())));
  expect_same_lines(*m, load_data("box.cao"), 1e-6, "fine_box.stl");
  EXPECT_EQ(m->faces().size(), 6u);
  std::printf("[ mesh     ] fine_box.stl %zu triangles, %zu -> %zu vertices, %zu sharp pieces -> %zu lines, %zu faces; "
              "read %.1f ms, extract %.1f ms, total %.1f ms\n",
              st.file_triangles, st.file_vertices, st.welded_vertices, st.sharp_pieces, m->lines().size(), m->faces().size(),
              st.read_ms, st.extract_ms, ms);
  EXPECT_LT(ms, 5000.0);
}

TEST(MeshReader, BuilderAddsFacesWithoutEdgesAndLinksLinesLater) {
  // The ModelBuilder calls the mesh import relies on.
  ModelBuilder b("square");
  for (const Vector3d& p : {Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(1, 1, 0), Vector3d(0, 1, 0)}) b.add_junction(p);
  auto f0 = b.add_face({0, 1, 2, 3}, {}, 1e-4, v4r::model::FaceEdges::kSkip);
  ASSERT_TRUE(f0);
  EXPECT_EQ(b.line_count(), 0u);
  EXPECT_EQ(b.face_count(), 1u);
  const Index l = b.add_line(0, 2);
  EXPECT_TRUE(b.set_line_faces(l, *f0, kNone));
  EXPECT_FALSE(b.set_line_faces(l, 5, kNone));
  EXPECT_FALSE(b.set_line_faces(7, *f0, kNone));
  auto m = std::move(b).build();
  ASSERT_TRUE(m);
  EXPECT_EQ(m->lines().size(), 1u);
  EXPECT_EQ(m->lines()[0].face_left, 0u);
  EXPECT_EQ(m->lines()[0].face_right, kNone);
}
