// v4r - robust model-based object tracking. MIT licence.
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <Eigen/Geometry>
#include <fmt/format.h>
#include <gtest/gtest.h>

#include "v4r/model/cao_reader.hpp"

namespace fs = std::filesystem;
using v4r::model::Index;
using v4r::model::kNone;
using v4r::model::CaoReadOptions;
using v4r::model::load_cao;
using v4r::model::Model;
using v4r::model::parse_cao;

namespace {

// A 0.12 x 0.075 x 0.033 m box (x in [0, 0.12], y in [0, 0.075], z in [-0.033, 0]); faces are
// listed counter-clockwise seen from outside.
const char* const kBox =
    "V1\n"
    "# 3D Points\n"
    "8                  # Number of points\n"
    "0     0      0     # Point 0: X Y Z\n"
    "0     0     -0.033\n"
    "0.12  0     -0.033\n"
    "0.12  0      0\n"
    "0.12  0.075  0\n"
    "0.12  0.075 -0.033\n"
    "0     0.075 -0.033\n"
    "0     0.075  0     # Point 7\n"
    "# 3D Lines\n"
    "0                  # Number of lines\n"
    "# Faces from 3D lines\n"
    "0                  # Number of faces\n"
    "# Faces from 3D points\n"
    "6                  # Number of faces\n"
    "4 0 1 2 3          # Face 0: [number of points] [index of the 3D points]...\n"
    "4 1 6 5 2\n"
    "4 4 5 6 7\n"
    "4 0 3 4 7\n"
    "4 5 4 3 2\n"
    "4 0 7 6 1          # Face 5\n"
    "# 3D cylinders\n"
    "0                  # Number of cylinders\n"
    "# 3D circles\n"
    "0                  # Number of circles\n";

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (std::size_t pos = 0; (pos = s.find(from, pos)) != std::string::npos; pos += to.size()) s.replace(pos, from.size(), to);
  return s;
}

std::string error_text(const v4r::Expected<Model>& m) { return m ? std::string("(no error)") : m.error().to_string(); }

/// Checks the box's topology and geometry: 8 junctions, 12 edges with two faces, outward normals.
void expect_valid_box(const Model& m) {
  ASSERT_EQ(m.junctions().size(), 8u);
  ASSERT_EQ(m.lines().size(), 12u);
  ASSERT_EQ(m.faces().size(), 6u);
  EXPECT_TRUE(m.arcs().empty());
  EXPECT_TRUE(m.cylinders().empty());
  EXPECT_LT((m.junctions()[5].p - Eigen::Vector3d(0.12, 0.075, -0.033)).norm(), 1e-15);
  for (const auto& j : m.junctions()) EXPECT_EQ(j.lines.size(), 3u);
  for (const auto& e : m.lines()) {
    EXPECT_NE(e.face_left, kNone);
    EXPECT_NE(e.face_right, kNone);
    EXPECT_NE(e.face_left, e.face_right);
    const double len = (m.junctions()[e.a].p - m.junctions()[e.b].p).norm();  // an axis-aligned box edge
    EXPECT_TRUE(std::abs(len - 0.12) < 1e-12 || std::abs(len - 0.075) < 1e-12 || std::abs(len - 0.033) < 1e-12) << len;
  }
  const Eigen::Vector3d centre(0.06, 0.0375, -0.0165);
  const Eigen::Vector3d expected_normals[6] = {{0, -1, 0}, {0, 0, -1}, {0, 1, 0}, {0, 0, 1}, {1, 0, 0}, {-1, 0, 0}};
  for (std::size_t f = 0; f < 6; ++f) {
    const auto& face = m.faces()[f];
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (Index j : face.loop) c += m.junctions()[j].p;
    c /= static_cast<double>(face.loop.size());
    EXPECT_GT(face.normal.dot(c - centre), 0.0) << "face " << f << " normal points inwards";
    EXPECT_LT((face.normal - expected_normals[f]).norm(), 1e-12) << "face " << f;
  }
  EXPECT_NEAR(m.bounding_radius(), std::sqrt(0.12 * 0.12 + 0.075 * 0.075 + 0.033 * 0.033), 1e-12);
}

/// A fresh directory under the test temp dir, removed at destruction.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    path_ = (fs::path(testing::TempDir()) /
             ("v4r_cao_" + std::string(info ? info->name() : "x") + "_" + std::to_string(::getpid()) + "_" +
              std::to_string(counter++)))
                .lexically_normal();
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  /// Writes `text` to `rel` (creating sub-directories); returns the full path.
  std::string write(const std::string& rel, const std::string& text) const {
    const fs::path p = path_ / rel;
    fs::create_directories(p.parent_path());
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }
  [[nodiscard]] std::string file(const std::string& rel) const { return (path_ / rel).string(); }

 private:
  fs::path path_;
};

/// A right triangle in the z = 0 plane (normal +z), as a complete .cao text.
const char* const kTriangle =
    "V1\n3\n0 0 0\n0.1 0 0\n0 0.2 0\n0\n0\n1\n3 0 1 2 name=tri\n";

}  // namespace

// ---- valid files --------------------------------------------------------------------------------

TEST(CaoReader, BoxFromFacesOfPoints) {
  auto m = parse_cao(kBox, "data/box.cao");
  ASSERT_TRUE(m) << error_text(m);
  expect_valid_box(*m);
  EXPECT_EQ(m->name(), "box");
}

struct Variant {
  const char* name;
  std::string text;
};

void PrintTo(const Variant& v, std::ostream* os) { *os << v.name; }

class CaoBoxVariants : public testing::TestWithParam<Variant> {};

TEST_P(CaoBoxVariants, ParseToTheSameBox) {
  auto m = parse_cao(GetParam().text, "box.cao");
  ASSERT_TRUE(m) << error_text(m);
  expect_valid_box(*m);
}

namespace {
std::vector<Variant> box_variants() {
  const std::string box = kBox;
  std::string commented;  // a comment on every line, blank lines and indentation in between
  for (std::size_t pos = 0, nl; (nl = box.find('\n', pos)) != std::string::npos; pos = nl + 1)
    commented += "\t " + box.substr(pos, nl - pos) + "   # remark, with 1 2 3 numbers\n\n";
  return {
      {"LF", box},
      {"CRLF", replace_all(box, "\n", "\r\n")},
      {"CR", replace_all(box, "\n", "\r")},
      {"WithoutV1", box.substr(3)},
      {"CommentsEverywhere", "# leading comment\n\n" + commented + "# trailing comment"},
      {"NoFinalNewline", box.substr(0, box.size() - 1)},
      {"NoCylinderAndCircleSections", box.substr(0, box.find("# 3D cylinders"))},
      {"NoCircleSection", box.substr(0, box.find("# 3D circles"))},
      {"ByteOrderMark", "\xEF\xBB\xBF" + box},
      {"Tabs", replace_all(box, " ", "\t")},
  };
}
}  // namespace

INSTANTIATE_TEST_SUITE_P(Formatting, CaoBoxVariants, testing::ValuesIn(box_variants()),
                         [](const testing::TestParamInfo<Variant>& i) { return std::string(i.param.name); });

TEST(CaoReader, FacesFromLinesAndNamedLines) {
  // A unit square in z = 0 from 4 lines listed out of order and partly reversed.
  const char* text =
      "V1\n"
      "4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
      "# 3D Lines\n"
      "4\n"
      "1 0 name=bottom useLod=true minLineLengthThreshold=0.05\n"
      "1 2 name=\"right edge\"\n"
      "3 0 name=left\n"
      "2 3 name=top\n"
      "# Faces from 3D lines\n"
      "1\n"
      "4 0 1 3 2 name=square minPolygonAreaThreshold=0.1\n"
      "# Faces from 3D points\n"
      "0\n";
  auto m = parse_cao(text, "square.cao");
  ASSERT_TRUE(m) << error_text(m);
  ASSERT_EQ(m->lines().size(), 4u);  // the face's edges are the named lines
  EXPECT_EQ(m->lines()[0].attr.name, "bottom");
  EXPECT_EQ(m->lines()[1].attr.name, "right edge");
  EXPECT_EQ(m->lines()[2].attr.name, "left");
  EXPECT_EQ(m->lines()[3].attr.name, "top");
  ASSERT_EQ(m->faces().size(), 1u);
  const auto& f = m->faces()[0];
  EXPECT_EQ(f.attr.name, "square");
  EXPECT_EQ(f.loop, (std::vector<Index>{0, 1, 2, 3}));  // walked in the listed order: 0 -> 1 -> 2 -> 3
  EXPECT_LT((f.normal - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
  for (const auto& e : m->lines()) {
    EXPECT_EQ(e.face_left, 0u);
    EXPECT_EQ(e.face_right, kNone);
  }
}

TEST(CaoReader, FaceColourAttribute) {
  // The paper's sponge: one face with a colour (RGB in 0..1), quoted or not, British or US key.
  const char* text =
      "V1\n4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0\n0\n2\n"
      "4 0 1 2 3 name=top colour=0.2,0.6,0.1\n"
      "3 0 1 2 color=\"1,0.5,0\"\n";
  auto m = parse_cao(text, "sponge.cao");
  ASSERT_TRUE(m) << error_text(m);
  ASSERT_EQ(m->faces().size(), 2u);
  ASSERT_TRUE(m->faces()[0].attr.colour.has_value());
  EXPECT_TRUE(m->faces()[0].attr.colour->isApprox(Eigen::Vector3f(0.2f, 0.6f, 0.1f)));
  EXPECT_EQ(m->faces()[0].attr.name, "top");
  ASSERT_TRUE(m->faces()[1].attr.colour.has_value());
  EXPECT_TRUE(m->faces()[1].attr.colour->isApprox(Eigen::Vector3f(1.0f, 0.5f, 0.0f)));
  EXPECT_FALSE(m->lines()[0].attr.colour.has_value());
}

TEST(CaoReader, FaceFromLinesFollowsTheListedDirection) {
  // Same square, lines listed clockwise: the loop, hence the normal, flips.
  const char* text = "4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4\n0 1\n1 2\n2 3\n3 0\n1\n4 3 2 1 0\n0\n";
  auto m = parse_cao(text, "sq.cao");
  ASSERT_TRUE(m) << error_text(m);
  EXPECT_EQ(m->faces()[0].loop, (std::vector<Index>{0, 3, 2, 1}));
  EXPECT_LT((m->faces()[0].normal + Eigen::Vector3d::UnitZ()).norm(), 1e-12);
}

TEST(CaoReader, Circles) {
  const char* text =
      "V1\n4\n0 0 0.1\n0.05 0 0.1\n0 0.05 0.1\n1 1 1\n0\n0\n0\n"
      "# 3D cylinders\n0\n"
      "# 3D circles\n2\n"
      "0.05 0 1 2 name=rim\n"
      "0.02 0 2 1\n";
  auto m = parse_cao(text, "disc.cao");
  ASSERT_TRUE(m) << error_text(m);
  ASSERT_EQ(m->arcs().size(), 2u);
  const auto& a = m->arcs()[0];
  EXPECT_EQ(a.attr.name, "rim");
  EXPECT_DOUBLE_EQ(a.radius, 0.05);
  EXPECT_LT((a.center - Eigen::Vector3d(0, 0, 0.1)).norm(), 1e-15);
  EXPECT_LT((a.normal - Eigen::Vector3d::UnitZ()).norm(), 1e-15);
  EXPECT_LT((a.x_axis - Eigen::Vector3d::UnitX()).norm(), 1e-15);
  EXPECT_DOUBLE_EQ(a.start, 0.0);
  EXPECT_DOUBLE_EQ(a.end, 2 * M_PI);
  EXPECT_EQ(a.face, kNone);
  const auto& b = m->arcs()[1];  // points swapped: the normal flips, the x axis follows point 2
  EXPECT_LT((b.normal + Eigen::Vector3d::UnitZ()).norm(), 1e-15);
  EXPECT_LT((b.x_axis - Eigen::Vector3d::UnitY()).norm(), 1e-15);
  EXPECT_NEAR(m->bounding_radius(), std::sqrt(3.0), 1e-15);
}

TEST(CaoReader, Cylinders) {
  const char* text =
      "V1\n# 3D Points\n4\n0 0 0\n0 0 0.2\n0.5 0 0\n0.5 0.3 0\n"
      "# 3D Lines\n0\n# Faces from 3D lines\n0\n# Faces from 3D points\n0\n"
      "# 3D cylinders\n2\n"
      "0 1 0.03 name=can\n"
      "2 3 +5e-3\n"
      "# 3D circles\n0\n";
  auto m = parse_cao(text, "cans.cao");
  ASSERT_TRUE(m) << error_text(m);
  ASSERT_EQ(m->cylinders().size(), 2u);
  ASSERT_EQ(m->arcs().size(), 4u);  // two rims per cylinder
  EXPECT_EQ(m->cylinders()[0].attr.name, "can");
  EXPECT_DOUBLE_EQ(m->cylinders()[0].radius, 0.03);
  EXPECT_DOUBLE_EQ(m->cylinders()[1].radius, 0.005);
  EXPECT_LT((m->cylinders()[1].p2 - Eigen::Vector3d(0.5, 0.3, 0)).norm(), 1e-15);
  EXPECT_LT((m->arcs()[1].center - Eigen::Vector3d(0, 0, 0.2)).norm(), 1e-15);
  EXPECT_LT((m->arcs()[0].normal - Eigen::Vector3d::UnitZ()).norm(), 1e-15);
  EXPECT_LT((m->arcs()[2].normal - Eigen::Vector3d::UnitY()).norm(), 1e-15);
  EXPECT_DOUBLE_EQ(m->arcs()[3].radius, 0.005);
  EXPECT_NEAR(m->bounding_radius(), std::hypot(0.5, 0.3) + 0.005, 1e-15);
}

// ---- includes -----------------------------------------------------------------------------------

TEST(CaoInclude, ChildLoadedTwiceWithDifferentPoses) {
  TempDir dir;
  dir.write("parts/tri.cao", kTriangle);
  const std::string parent = dir.write(
      "assembly.cao",
      "V1\n"
      "load(\"parts/tri.cao\", t=[1.0, 2.0, 3.0], tu=[0, 0, 1.5707963267948966])  # 90 deg about z\n"
      "  load( \"./parts/../parts/tri.cao\" , tu=[3.141592653589793 0 0] , t=[0 0 0.5] )\n"
      "# own points: indices 0..2 refer to these, not to the included ones\n"
      "3\n0 0 1\n0 0.1 1\n-0.1 0 1\n0\n0\n1\n3 0 1 2 name=own\n");
  auto m = load_cao(parent);
  ASSERT_TRUE(m) << error_text(m);
  EXPECT_EQ(m->name(), "assembly");
  ASSERT_EQ(m->junctions().size(), 9u);
  ASSERT_EQ(m->faces().size(), 3u);
  ASSERT_EQ(m->lines().size(), 9u);
  // First copy: p' = Rz(90) p + (1, 2, 3).
  const Eigen::Vector3d first[3] = {{1, 2, 3}, {1, 2.1, 3}, {0.8, 2, 3}};
  // Second copy: p' = Rx(180) p + (0, 0, 0.5).
  const Eigen::Vector3d second[3] = {{0, 0, 0.5}, {0.1, 0, 0.5}, {0, -0.2, 0.5}};
  for (int k = 0; k < 3; ++k) {
    EXPECT_LT((m->junctions()[k].p - first[k]).norm(), 1e-12) << k;
    EXPECT_LT((m->junctions()[3 + k].p - second[k]).norm(), 1e-12) << k;
  }
  EXPECT_LT((m->faces()[0].normal - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_LT((m->faces()[1].normal + Eigen::Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_EQ(m->faces()[0].attr.name, "tri");
  EXPECT_EQ(m->faces()[1].loop, (std::vector<Index>{3, 4, 5}));
  EXPECT_EQ(m->faces()[2].loop, (std::vector<Index>{6, 7, 8}));  // parent's own points
  EXPECT_EQ(m->faces()[2].attr.name, "own");
  EXPECT_LT((m->junctions()[7].p - Eigen::Vector3d(0, 0.1, 1)).norm(), 1e-15);
}

TEST(CaoInclude, NestedIncludesComposeTransforms) {
  TempDir dir;
  dir.write("a/b/child.cao", kTriangle);
  dir.write("a/mid.cao", "load(\"b/child.cao\", t=[1, 0, 0], tu=[0, 0, 1.5707963267948966])\n0\n0\n0\n0\n");
  const std::string top =
      dir.write("top.cao", "V1\nload(\"a/mid.cao\", t=[0, 0, 1], tu=[1.5707963267948966, 0, 0])\n0\n0\n0\n0\n");
  auto m = load_cao(top);
  ASSERT_TRUE(m) << error_text(m);
  ASSERT_EQ(m->junctions().size(), 3u);
  // child -> mid: Rz(90) p + (1,0,0); mid -> top: Rx(90) q + (0,0,1).
  const Eigen::Vector3d expected[3] = {{1, 0, 1}, {1, 0, 1.1}, {0.8, 0, 1}};
  for (int k = 0; k < 3; ++k) EXPECT_LT((m->junctions()[k].p - expected[k]).norm(), 1e-12) << k;
  EXPECT_LT((m->faces()[0].normal - Eigen::Vector3d(0, -1, 0)).norm(), 1e-12);
}

TEST(CaoInclude, CycleIsReportedWithTheChain) {
  TempDir dir;
  const std::string a = dir.write("a.cao", "V1\nload(\"b.cao\")\n0\n0\n0\n0\n");
  const std::string b = dir.write("b.cao", "V1\n# b includes a again\n   load(\"a.cao\", t=[0, 0, 0])\n0\n0\n0\n0\n");
  auto m = load_cao(a);
  ASSERT_FALSE(m);
  EXPECT_EQ(m.error().file, b);
  EXPECT_EQ(m.error().line, 3);
  EXPECT_EQ(m.error().column, 4);
  EXPECT_NE(m.error().message.find("include cycle: " + a + " -> " + b + " -> " + a), std::string::npos)
      << m.error().message;
  EXPECT_NE(m.error().message.find("included from " + a + ":2"), std::string::npos) << m.error().message;
}

TEST(CaoInclude, SelfIncludeIsACycle) {
  TempDir dir;
  const std::string a = dir.write("self.cao", "load(\"self.cao\")\n0\n0\n0\n0\n");
  auto m = load_cao(a);
  ASSERT_FALSE(m);
  EXPECT_EQ(m.error().line, 1);
  EXPECT_EQ(m.error().column, 1);
  EXPECT_NE(m.error().message.find("include cycle: " + a + " -> " + a), std::string::npos) << m.error().message;
}

TEST(CaoInclude, MissingFileIsReportedAtTheLoadStatement) {
  TempDir dir;
  const std::string p = dir.write("p.cao", "V1\n# parts\n\t load(\"missing/part.cao\", t=[0 0 0])\n0\n0\n0\n0\n");
  auto m = load_cao(p);
  ASSERT_FALSE(m);
  EXPECT_EQ(m.error().file, p);
  EXPECT_EQ(m.error().line, 3);
  EXPECT_EQ(m.error().column, 3);
  EXPECT_NE(m.error().message.find("cannot open included file 'missing/part.cao'"), std::string::npos)
      << m.error().message;
}

TEST(CaoInclude, ErrorInsideAnIncludedFileNamesThatFile) {
  TempDir dir;
  const std::string child = dir.write("child.cao", "3\n0 0 0\n1 0 0\n0 zero 0\n0\n0\n0\n");
  const std::string p = dir.write("p.cao", "load(\"child.cao\")\n0\n0\n0\n0\n");
  auto m = load_cao(p);
  ASSERT_FALSE(m);
  EXPECT_EQ(m.error().file, child);
  EXPECT_EQ(m.error().line, 4);
  EXPECT_EQ(m.error().column, 3);
  EXPECT_NE(m.error().message.find("'zero'"), std::string::npos) << m.error().message;
  EXPECT_NE(m.error().message.find("included from " + p + ":1"), std::string::npos) << m.error().message;
}

TEST(CaoInclude, LoadCaoReportsAMissingTopLevelFile) {
  TempDir dir;
  auto m = load_cao(dir.file("nothing_here.cao"));
  ASSERT_FALSE(m);
  EXPECT_EQ(m.error().file, dir.file("nothing_here.cao"));
  EXPECT_NE(m.error().message.find("cannot open"), std::string::npos);
}

// ---- faces that are not exactly planar (CAD exports, hand-measured models) ----------------------

namespace {

/// A 0.08 x 0.08 m square in z = 0 whose corners are lifted alternately by +d and -d, so its
/// least-squares plane is z = 0 and every corner is d off it; the diameter is the diagonal.
/// The face record is on line 11.
std::string warped_square(double d) {
  return fmt::format(
      "V1\n# a warped square\n4\n0 0 {}\n0.08 0 {}\n0.08 0.08 {}\n0 0.08 {}\n0\n0\n1\n4 0 1 2 3 name=lid\n0\n0\n",
      d, -d, d, -d);
}
constexpr double kDiagonal = 0.08 * 1.4142135623730951;

}  // namespace

TEST(CaoPlanarity, SlightlyWarpedFaceLoadsWithOneWarningNamingFileLineAndOffset) {
  const double d = 0.015 * kDiagonal;  // 1.5 % of the diameter: 1.7 mm
  std::vector<v4r::Error> warnings;
  auto m = parse_cao(warped_square(d), "warped.cao", {}, &warnings);
  ASSERT_TRUE(m) << m.error().to_string();
  ASSERT_EQ(m->faces().size(), 1u);
  // The face gets its least-squares plane: normal +z (CCW seen from +z).
  EXPECT_NEAR(m->faces()[0].normal.z(), 1.0, 1e-12);
  EXPECT_EQ(m->faces()[0].attr.name, "lid");
  EXPECT_EQ(m->lines().size(), 4u);
  ASSERT_EQ(warnings.size(), 1u);
  const v4r::Error& w = warnings[0];
  EXPECT_EQ(w.file, "warped.cao");
  EXPECT_EQ(w.line, 11);
  EXPECT_EQ(w.column, 1);
  EXPECT_NE(w.message.find("face 0 is not planar"), std::string::npos) << w.message;
  EXPECT_NE(w.message.find(fmt::format("{:.3g} m off", d)), std::string::npos) << w.message;
  EXPECT_NE(w.message.find("1.5 %"), std::string::npos) << w.message;
  EXPECT_NE(w.to_string().find("warped.cao:11:1: "), std::string::npos) << w.to_string();
}

TEST(CaoPlanarity, FaceOffPlaneBeyondTheBoundIsRefusedWithFileLineColumn) {
  const double d = 0.18 * kDiagonal;  // 18 %
  std::vector<v4r::Error> warnings;
  auto m = parse_cao(warped_square(d), "warped.cao", {}, &warnings);
  ASSERT_FALSE(m) << "an 18 % warped face was accepted";
  EXPECT_EQ(m.error().file, "warped.cao");
  EXPECT_EQ(m.error().line, 11);
  // The column is that of the worst point's index (all four are equally off here).
  EXPECT_TRUE(m.error().column == 3 || m.error().column == 5 || m.error().column == 7 || m.error().column == 9)
      << m.error().to_string();
  EXPECT_NE(m.error().message.find("18 % of its 0.113 m diameter"), std::string::npos) << m.error().message;
  EXPECT_NE(m.error().message.find("max_off_plane"), std::string::npos) << m.error().message;
}

TEST(CaoPlanarity, TheIssueExample_0_75mmOver8cmLoads) {
  // Today's complaint: a face 0.75 mm off-plane over 8 cm was refused (tolerance 0.128 mm).
  const std::string text = "4\n0 0 0\n0.08 0 0\n0.08 0.08 0.00075\n0 0.08 0\n0\n0\n1\n4 0 1 2 3\n";
  std::vector<v4r::Error> warnings;
  auto m = parse_cao(text, "part.cao", {}, &warnings);
  ASSERT_TRUE(m) << m.error().to_string();
  EXPECT_EQ(warnings.size(), 1u);
}

TEST(CaoPlanarity, PlanarAndNearlyPlanarFacesGiveNoWarning) {
  std::vector<v4r::Error> warnings;
  ASSERT_TRUE(parse_cao(warped_square(0.0), "flat.cao", {}, &warnings));
  ASSERT_TRUE(parse_cao(warped_square(0.00005), "flat.cao", {}, &warnings));  // 0.05 mm: CAD rounding
  EXPECT_TRUE(warnings.empty()) << warnings.front().to_string();
}

TEST(CaoPlanarity, TheBoundIsAReaderOption) {
  const std::string text = warped_square(0.015 * kDiagonal);
  CaoReadOptions strict;
  strict.max_off_plane = 0.01;
  auto m = parse_cao(text, "warped.cao", strict);
  ASSERT_FALSE(m);
  EXPECT_EQ(m.error().line, 11);
  EXPECT_NE(m.error().message.find("refused above 1 %"), std::string::npos) << m.error().message;

  CaoReadOptions lax;
  lax.max_off_plane = 0.25;
  std::vector<v4r::Error> warnings;
  EXPECT_TRUE(parse_cao(warped_square(0.18 * kDiagonal), "warped.cao", lax, &warnings));
  EXPECT_EQ(warnings.size(), 1u);

  for (double bad : {-0.1, 1.5, std::nan("")}) {
    CaoReadOptions o;
    o.max_off_plane = bad;
    auto e = parse_cao(text, "warped.cao", o);
    ASSERT_FALSE(e);
    EXPECT_EQ(e.error().field, "max_off_plane");
  }
}

TEST(CaoPlanarity, WarningInsideAnIncludedFileNamesThatFile) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("v4r_cao_planarity_{}", ::getpid());
  fs::create_directories(dir);
  {
    std::ofstream(dir / "part.cao") << warped_square(0.015 * kDiagonal);
    std::ofstream(dir / "top.cao") << "V1\nload(\"part.cao\", t=[0, 0, 0.5])\n0\n0\n0\n0\n";
  }
  std::vector<v4r::Error> warnings;
  auto m = load_cao((dir / "top.cao").string(), {}, &warnings);
  ASSERT_TRUE(m) << m.error().to_string();
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].file.find("part.cao"), std::string::npos) << warnings[0].to_string();
  EXPECT_EQ(warnings[0].line, 11);
  fs::remove_all(dir);
}

// ---- malformed input ----------------------------------------------------------------------------

struct BadCase {
  const char* name;
  std::string text;
  int line;
  int column;
  const char* fragment;
};

void PrintTo(const BadCase& c, std::ostream* os) { *os << c.name; }

class CaoMalformed : public testing::TestWithParam<BadCase> {};

TEST_P(CaoMalformed, ReportsLineColumnAndReason) {
  const BadCase& c = GetParam();
  auto m = parse_cao(c.text, "bad.cao");
  ASSERT_FALSE(m) << "parsed a malformed file";
  EXPECT_EQ(m.error().file, "bad.cao");
  EXPECT_EQ(m.error().line, c.line) << m.error().to_string();
  EXPECT_EQ(m.error().column, c.column) << m.error().to_string();
  EXPECT_NE(m.error().message.find(c.fragment), std::string::npos) << m.error().to_string();
}

namespace {
// Three points of a triangle, used as the prefix of most cases (lines 1-4).
const std::string kPts = "3\n0 0 0\n1 0 0\n0 1 0\n";
// Square points for face cases (lines 1-5).
const std::string kSq = "4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n";

std::vector<BadCase> bad_cases() {
  return {
      {"Empty", "", 1, 1, "end of file: expected the number of points"},
      {"TruncatedInPoints", "3\n0 0 0\n1 0 0\n", 4, 1, "end of file: expected 3 points, found 2"},
      {"TruncatedInFaces", kPts + "0\n0\n2\n3 0 1 2", 8, 8, "end of file: expected 2 faces from points, found 1"},
      {"TruncatedBeforeFaces", kPts + "0\n0\n", 7, 1, "expected the number of faces from points"},
      {"BadNumber", "3\n0 0 0\n1 x 0\n0 1 0\n0\n0\n0\n", 3, 3, "expected a number for coordinate y of point 1, found 'x'"},
      {"NaN", "3\n0 0 0\n1 0 nan\n0 1 0\n0\n0\n0\n", 3, 5, "finite number, found 'nan'"},
      {"Infinity", "3\n0 0 0\n-inf 0 0\n0 1 0\n0\n0\n0\n", 3, 1, "finite number, found '-inf'"},
      {"Overflow", "3\n0 0 0\n1e999 0 0\n0 1 0\n0\n0\n0\n", 3, 1, "'1e999' is out of range"},
      {"MissingCoordinate", "3\n0 0 0\n1 0\n0 1 0\n0\n0\n0\n", 3, 4, "point 1 (x y z) needs 3 values, found 2"},
      {"ExtraCoordinate", "3\n0 0 0\n1 0 0 7\n0 1 0\n0\n0\n0\n", 3, 7, "unexpected '7' after the 3 coordinates"},
      {"FewerPointsThanAnnounced", "4\n0 0 0\n1 0 0\n0 1 0\n# 3D Lines\n0\n0\n0\n", 6, 1,
       "expected 4 points, found 3 before this line"},
      {"MorePointsThanAnnounced", "2\n0 0 0\n1 0 0\n0 1 0\n0\n0\n0\n", 4, 3,
       "does the points section hold more than the 2 announced?"},
      {"NegativeCount", "-3\n", 1, 1, "the number of points must be >= 0, found -3"},
      {"FractionalCount", kPts + "1.5\n", 5, 1, "expected the number of lines (an integer), found '1.5'"},
      {"HugeCount", "99999999999999999999\n", 1, 1, "the number of points is too large"},
      {"LineIndexOutOfRange", kPts + "1\n0 3\n0\n0\n", 6, 3, "point index 3 is out of range (this file defines 3 points, 0..2)"},
      {"NegativeIndex", kPts + "1\n-1 2\n0\n0\n", 6, 1, "point index -1 is out of range"},
      {"ZeroLengthLine", "2\n0 0 0\n0 0 0\n1\n0 1\n0\n0\n", 5, 3, "zero length"},
      {"FaceIndexOutOfRange", kPts + "0\n0\n1\n3 0 1 5\n", 8, 7, "point index 5 is out of range"},
      {"FaceWithTwoPoints", kPts + "0\n0\n1\n2 0 1\n", 8, 1, "a face needs at least 3 points, found 2"},
      {"FaceShorterThanAnnounced", kSq + "0\n0\n1\n4 0 1 2 name=q\n", 9, 9, "face 0 announces 4 points but lists 3"},
      {"FaceRepeatsAPoint", kSq + "0\n0\n1\n4 0 1 2 1\n", 9, 9, "face 0 lists point 1 twice"},
      // Point 3 is 0.259 m off the least-squares plane, 18.3 % of the 1.414 m diameter (bound 10 %):
      // the column is that of point 3's index.
      {"NonPlanarFace", "5\n0 0 0\n1 0 0\n1 1 0\n0.5 1 0.4\n0 1 0\n0\n0\n1\n5 0 1 2 3 4\n", 10, 9,
       "face 0 is not planar: point 3 is 0.259 m off the face's least-squares plane, 18.3 % of its 1.41 m diameter"},
      {"DegenerateFace", "3\n0 0 0\n1 0 0\n2 0 0\n0\n0\n1\n3 0 1 2\n", 8, 1, "face 0 is degenerate: its points enclose no area"},
      {"FaceCountTooLarge", kPts + "0\n0\n1\n99999999999999999999 0 1 2\n", 8, 1, "the number of points is too large"},
      {"FaceLongerThanItsLine", kPts + "0\n0\n1\n1000000 0 1 2\n", 8, 14, "announces 1000000 points but lists 3"},
      {"CoincidentFacePoints", "3\n0 0 0\n1 0 0\n1 0 0\n0\n0\n1\n3 0 1 2\n", 8, 1, "points 1 and 2 coincide"},
      {"FaceLinesNotClosed", kSq + "3\n0 1\n1 2\n2 3\n1\n3 0 1 2\n0\n", 11, 3, "do not form one closed loop"},
      {"FaceLinesTwoLoops", "6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 1\n0 1 1\n6\n0 1\n1 2\n2 0\n3 4\n4 5\n5 3\n1\n6 0 1 2 3 4 5\n0\n",
       16, 1, "several loops"},
      {"FaceLineIndexOutOfRange", kSq + "1\n0 1\n1\n3 0 1 1\n0\n", 9, 5, "line index 1 is out of range (this file defines 1 lines"},
      {"BadAttribute", kPts + "1\n0 1 name\n0\n0\n", 6, 5, "malformed attribute 'name': expected key=value"},
      {"AttributeWithoutKey", kPts + "1\n0 1 =edge\n0\n0\n", 6, 5, "the key must be a name"},
      {"AttributeWithoutValue", kPts + "1\n0 1 name=\n0\n0\n", 6, 10, "attribute 'name' has no value"},
      {"UnterminatedQuotedValue", kPts + "1\n0 1 name=\"a b\n0\n0\n", 6, 10, "unterminated quoted value"},
      {"ColourWithTwoValues", kSq + "0\n0\n1\n4 0 1 2 3 colour=0.2,0.6\n", 9, 18, "colour needs 3 values R,G,B"},
      {"ColourWithFourValues", kSq + "0\n0\n1\n4 0 1 2 3 colour=0.2,0.6,0.1,1\n", 9, 29, "found more in"},
      {"ColourOutOfRange", kSq + "0\n0\n1\n4 0 1 2 3 colour=0.2,1.5,0.1\n", 9, 22, "component G must be a number in 0..1, found '1.5'"},
      {"ColourNotANumber", kSq + "0\n0\n1\n4 0 1 2 3 color=0.2,0.6,green\n", 9, 25, "component B must be a number in 0..1, found 'green'"},
      {"BadUseLod", kPts + "1\n0 1 useLod=maybe\n0\n0\n", 6, 12, "useLod must be true or false"},
      {"BadThreshold", kPts + "1\n0 1 minLineLengthThreshold=-1\n0\n0\n", 6, 28, "must be a finite number >= 0"},
      {"GarbageAfterLastSection", kPts + "0\n0\n0\n0\n0\nhello world\n", 10, 1, "unexpected 'hello' after the last section"},
      {"GarbageInsteadOfCount", kPts + "lines\n", 5, 1, "expected the number of lines (an integer), found 'lines'"},
      {"ZeroRadiusCylinder", "2\n0 0 0\n0 0 1\n0\n0\n0\n1\n0 1 0\n", 8, 5, "radius of cylinder 0 must be > 0"},
      {"NegativeRadiusCircle", kPts + "0\n0\n0\n0\n1\n-0.5 0 1 2\n", 10, 1, "radius of circle 0 must be > 0"},
      {"ZeroLengthCylinderAxis", "2\n0 0 0\n0 0 0\n0\n0\n0\n1\n0 1 0.1\n", 8, 3, "zero-length axis"},
      {"CollinearCirclePoints", "3\n0 0 0\n1 0 0\n2 0 0\n0\n0\n0\n0\n1\n0.5 0 1 2\n", 10, 5, "are collinear"},
      {"CircleMissingIndex", kPts + "0\n0\n0\n0\n1\n0.5 0 1\n", 10, 8, "needs 4 values, found 3"},
      {"UnterminatedLoad", "V1\nload(\"part.cao\", t=[0, 0, 0]  # comment\n0\n0\n0\n0\n", 2, 31, "unterminated load(...)"},
      {"UnterminatedLoadFileName", "load(\"part.cao\n", 1, 6, "unterminated file name"},
      {"LoadUnknownParameter", "load(\"part.cao\", r=[0, 0, 0])\n", 1, 18, "unknown load parameter 'r'"},
      {"LoadTooFewValues", "load(\"part.cao\", t=[0, 0])\n", 1, 25, "'t' needs 3 values, found 2"},
      {"LoadNaN", "load(\"part.cao\", tu=[0, nan, 0])\n", 1, 25, "finite number"},
      {"LoadTrailingText", "load(\"part.cao\") extra\n", 1, 18, "unexpected 'extra' after load(...)"},
      {"LoadAfterPoints", kPts + "load(\"part.cao\")\n", 5, 1, "only allowed before the points section"},
      {"UnsupportedVersion", "V2\n0\n0\n0\n0\n", 1, 1, "unsupported .cao version 'V2'"},
  };
}
}  // namespace

INSTANTIATE_TEST_SUITE_P(Table, CaoMalformed, testing::ValuesIn(bad_cases()),
                         [](const testing::TestParamInfo<BadCase>& i) { return std::string(i.param.name); });

TEST(CaoMalformedCrlf, PositionsAreTheSameWithCrlf) {
  const std::string text = replace_all("V1\n3\n0 0 0\n1 0 0\n0 1 0\n0\n0\n1\n3 0 1 9\n", "\n", "\r\n");
  auto m = parse_cao(text, "crlf.cao");
  ASSERT_FALSE(m);
  EXPECT_EQ(m.error().line, 9);
  EXPECT_EQ(m.error().column, 7);
  EXPECT_EQ(m.error().to_string().substr(0, 13), "crlf.cao:9:7:");
}

TEST(CaoMalformedFuzz, NeverCrashesOnTruncatedOrMutatedBoxes) {
  // Every prefix of the box and single-byte mutations either parse or yield a located error.
  const std::string box = kBox;
  const char replacements[] = {'#', '\n', 'x', '-', '9', ' ', '"', '=', '.', '\0'};
  int errors = 0, parsed = 0;
  auto check = [&](const std::string& text) {
    auto m = parse_cao(text, "fuzz.cao");
    if (m) {
      ++parsed;
      return;
    }
    ++errors;
    EXPECT_GE(m.error().line, 1) << m.error().to_string();
    EXPECT_GE(m.error().column, 1) << m.error().to_string();
    EXPECT_FALSE(m.error().message.empty());
  };
  for (std::size_t n = 0; n <= box.size(); n += 3) check(box.substr(0, n));
  for (std::size_t i = 0; i < box.size(); i += 2) {
    for (char r : replacements) {
      std::string t = box;
      t[i] = r;
      check(t);
    }
  }
  EXPECT_GT(errors, 100);
  EXPECT_GT(parsed, 100);  // mutations inside comments are harmless
}
