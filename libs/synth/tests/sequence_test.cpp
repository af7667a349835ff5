// v4r - robust model-based object tracking. MIT licence.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include "v4r/io/camera_io.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/synth/conditions.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::synth {
namespace {

namespace fs = std::filesystem;

std::string read_file(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// The repository root, from this file's path (libs/synth/tests/sequence_test.cpp).
// From CMake: __FILE__ is relative to the build folder when ccache (CCACHE_BASEDIR) or Ninja
// rewrite the paths, and ctest runs the tests elsewhere.
fs::path repo_root() { return fs::path(V4R_SOURCE_DIR); }

/// A fresh scratch directory, removed at the end of the test.
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& name)
      : path_(fs::temp_directory_path() / ("v4r_synth_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

TEST(Models, DataFilesEqualTheBuiltInModels) {
  EXPECT_EQ(read_file(repo_root() / "data" / "box.cao"), box_cao());
  EXPECT_EQ(read_file(repo_root() / "data" / "ship_mockup.cao"), ship_mockup_cao());
  EXPECT_EQ(read_file(repo_root() / "data" / "flange.cao"), flange_cao());
}

TEST(Models, FlangeIsAPlateWithACylinderAndItsTwoRims) {
  auto m = model::parse_cao(flange_cao(), "flange.cao");
  ASSERT_TRUE(m.has_value()) << m.error().to_string();
  EXPECT_EQ(m->faces().size(), 6u);
  EXPECT_EQ(m->lines().size(), 12u);
  for (const auto& l : m->lines()) EXPECT_NE(l.face_right, model::kNone);  // a closed plate
  // Plate 0.20 x 0.20 x 0.02 m below z = 0, centred on the origin; outward normals.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const auto& f : m->faces())
    for (auto j : f.loop) {
      lo = lo.cwiseMin(m->junctions()[j].p);
      hi = hi.cwiseMax(m->junctions()[j].p);
    }
  EXPECT_TRUE(lo.isApprox(Eigen::Vector3d(-0.10, -0.10, -0.02)));
  EXPECT_TRUE(hi.isApprox(Eigen::Vector3d(0.10, 0.10, 0.0)));
  for (const auto& f : m->faces()) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (auto j : f.loop) c += m->junctions()[j].p;
    c /= static_cast<double>(f.loop.size());
    EXPECT_GT(f.normal.dot(c - Eigen::Vector3d(0, 0, -0.01)), 0.0);
  }
  // One cylinder on the plate's top face, axis z, radius 0.05 m, height 0.06 m ...
  ASSERT_EQ(m->cylinders().size(), 1u);
  const model::Cylinder& cyl = m->cylinders()[0];
  EXPECT_TRUE(cyl.p1.isZero(1e-12));
  EXPECT_TRUE(cyl.p2.isApprox(Eigen::Vector3d(0, 0, 0.06)));
  EXPECT_DOUBLE_EQ(cyl.radius, 0.05);
  // ... and its two rims once each (not duplicated by .cao circles).
  ASSERT_EQ(m->arcs().size(), 2u);
  EXPECT_NEAR(m->arcs()[0].center.z(), 0.0, 1e-12);
  EXPECT_NEAR(m->arcs()[1].center.z(), 0.06, 1e-12);
  for (const auto& a : m->arcs()) {
    EXPECT_DOUBLE_EQ(a.radius, 0.05);
    EXPECT_NEAR(std::abs(a.normal.z()), 1.0, 1e-12);
  }
}

TEST(Models, BoxHasTheRightSizeAndOutwardNormals) {
  auto m = model::parse_cao(box_cao(), "box.cao");
  ASSERT_TRUE(m.has_value()) << m.error().to_string();
  EXPECT_EQ(m->junctions().size(), 8u);
  EXPECT_EQ(m->lines().size(), 12u);
  EXPECT_EQ(m->faces().size(), 6u);
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const auto& j : m->junctions()) {
    lo = lo.cwiseMin(j.p);
    hi = hi.cwiseMax(j.p);
  }
  EXPECT_TRUE((hi - lo).isApprox(Eigen::Vector3d(0.20, 0.15, 0.10)));
  EXPECT_TRUE((hi + lo).isZero(1e-12));  // centred
  for (const auto& f : m->faces()) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (auto j : f.loop) c += m->junctions()[j].p;
    EXPECT_GT(f.normal.dot(c), 0.0);  // outward (the box is convex and centred)
  }
  for (const auto& l : m->lines()) EXPECT_NE(l.face_right, model::kNone);  // closed: two faces per edge
}

TEST(Models, ShipMockupIsWellFormed) {
  auto m = model::parse_cao(ship_mockup_cao(), "ship_mockup.cao");
  ASSERT_TRUE(m.has_value()) << m.error().to_string();
  EXPECT_EQ(m->faces().size(), 15u);
  // Base plate top face at z = 0, with the origin at its centre.
  double zmin = 1e9, zmax = -1e9;
  for (const auto& j : m->junctions()) {
    zmin = std::min(zmin, j.p.z());
    zmax = std::max(zmax, j.p.z());
  }
  EXPECT_DOUBLE_EQ(zmin, -0.02);
  EXPECT_DOUBLE_EQ(zmax, 0.12);
  // Outward normals: every face's normal points away from the centre of the box it belongs to,
  // i.e. the face's points lie on the far side of the plate/wall centre.
  const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> boxes{{{-0.20, -0.15, -0.02}, {0.20, 0.15, 0.0}},
                                                                       {{-0.18, 0.10, 0.0}, {0.18, 0.12, 0.12}},
                                                                       {{0.06, -0.13, 0.0}, {0.08, 0.10, 0.10}}};
  for (const auto& f : m->faces()) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (auto j : f.loop) c += m->junctions()[j].p;
    c /= static_cast<double>(f.loop.size());
    bool found = false;
    for (const auto& [lo, hi] : boxes) {
      if ((c.array() >= lo.array() - 1e-9).all() && (c.array() <= hi.array() + 1e-9).all()) {
        EXPECT_GT(f.normal.dot(c - 0.5 * (lo + hi)), 0.0);
        found = true;
        break;
      }
    }
    EXPECT_TRUE(found);
  }
}

TEST(Sequence, WritesAllFiles) {
  ScratchDir dir("seq");
  const fs::path root = dir.path() / "a" / "b";  // nested: created on demand
  TrajectorySpec spec;
  spec.frames = 3;
  spec.T0 = geometry::look_at(Eigen::Vector3d(0.2, -0.4, 0.35), Eigen::Vector3d::Zero());
  const auto traj = make_trajectory(spec);
  RenderOptions opt;
  opt.colour = false;
  const auto cam = default_camera();
  auto r = write_sequence(root.string(), box_cao(), cam, traj, opt);
  ASSERT_TRUE(r.has_value()) << r.error().to_string();
  for (int i = 0; i < 3; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    const cv::Mat img = cv::imread((root / "frames" / name).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(img.empty()) << name;
    EXPECT_EQ(img.cols, 640);
    EXPECT_EQ(img.rows, 480);
    EXPECT_EQ(img.type(), CV_8UC1);
    // The frame is the renderer's output for that frame index.
    const Renderer ren(cam, opt);
    const model::Model box = model::parse_cao(box_cao(), "box").value();
    EXPECT_EQ(cv::norm(img, ren.render(box, traj[static_cast<std::size_t>(i)], i), cv::NORM_INF), 0.0);
  }
  EXPECT_FALSE(fs::exists(root / "frames" / "000003.png"));
  EXPECT_EQ(read_file(root / "model.cao"), box_cao());

  auto rows = io::load_pose_csv((root / "gt.csv").string());
  ASSERT_TRUE(rows.has_value()) << rows.error().to_string();
  ASSERT_EQ(rows->size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ((*rows)[static_cast<std::size_t>(i)].frame, i);
    EXPECT_LT(
        ((*rows)[static_cast<std::size_t>(i)].T_cam_obj.translation() - traj[static_cast<std::size_t>(i)].translation())
            .norm(),
        1e-6);
    EXPECT_LT(geometry::rotation_angle_between((*rows)[static_cast<std::size_t>(i)].T_cam_obj,
                                               traj[static_cast<std::size_t>(i)]),
              1e-6);
  }
  auto init = io::load_pose_file((root / "init_pose.txt").string());
  ASSERT_TRUE(init.has_value()) << init.error().to_string();
  EXPECT_LT((init->translation() - traj[0].translation()).norm(), 1e-6);
  EXPECT_LT(geometry::rotation_angle_between(*init, traj[0]), 1e-6);
  auto c = io::load_camera((root / "camera.yaml").string());
  ASSERT_TRUE(c.has_value()) << c.error().to_string();
  EXPECT_EQ(c->width, 640);
  EXPECT_EQ(c->height, 480);
  EXPECT_NEAR(c->fx, 600.0, 1e-9);
  EXPECT_NEAR(c->cx, 319.5, 1e-9);
  EXPECT_NEAR(c->dist[0], -0.05, 1e-12);
  EXPECT_NEAR(c->dist[1], 0.01, 1e-12);

  // A shorter sequence written into the same directory leaves no stale frames behind.
  const std::vector<geometry::SE3> two(traj.begin(), traj.begin() + 2);
  r = write_sequence(root.string(), box_cao(), cam, two, opt);
  ASSERT_TRUE(r.has_value()) << r.error().to_string();
  EXPECT_TRUE(fs::exists(root / "frames" / "000001.png"));
  EXPECT_FALSE(fs::exists(root / "frames" / "000002.png"));
  rows = io::load_pose_csv((root / "gt.csv").string());
  ASSERT_TRUE(rows.has_value());
  EXPECT_EQ(rows->size(), 2u);
}

TEST(Sequence, AppliesTheConditionsOverTheSequence) {
  ScratchDir dir("cond");
  TrajectorySpec spec;
  spec.frames = 4;
  spec.T0 = geometry::look_at(0.6, -0.6, 0.75);
  const auto traj = make_trajectory(trajectory_spec_for(Condition::kFast, spec));
  RenderOptions opt =
      options_for(Condition::kBlur, options_for(Condition::kOcclusion, options_for(Condition::kShadow)));
  opt.colour = false;
  const auto cam = default_camera();
  auto r = write_sequence(dir.path().string(), flange_cao(), cam, traj, opt);
  ASSERT_TRUE(r.has_value()) << r.error().to_string();
  // The frames are the renderer's, with a cycle of the sequence's length, the scene laid out
  // for this trajectory and each frame exposed from the previous pose (frame 0: extrapolated).
  const model::Model m = model::parse_cao(flange_cao(), "flange").value();
  RenderOptions o = opt;
  o.cycle_frames = 4;
  Renderer ren(cam, o);
  ren.set_scene_reference(m, traj);
  const geometry::SE3 before = traj[0] * traj[1].inverse() * traj[0];
  for (int i = 0; i < 4; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    const cv::Mat img = cv::imread((dir.path() / "frames" / name).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(img.empty()) << name;
    const auto k = static_cast<std::size_t>(i);
    EXPECT_EQ(cv::norm(img, ren.render(m, traj[k], i, i > 0 ? &traj[k - 1] : &before), cv::NORM_INF), 0.0) << name;
  }
  EXPECT_EQ(read_file(dir.path() / "model.cao"), flange_cao());
}

TEST(Sequence, ErrorsNameThePath) {
  ScratchDir dir("err");
  const auto traj = make_trajectory(
      TrajectorySpec{.frames = 1, .T0 = geometry::look_at(Eigen::Vector3d(0, -0.5, 0.3), Eigen::Vector3d::Zero())});
  // A directory below a regular file cannot be created.
  const fs::path blocker = dir.path() / "file";
  std::ofstream(blocker) << "x";
  const fs::path bad_dir = blocker / "seq";
  auto r = write_sequence(bad_dir.string(), box_cao(), default_camera(), traj, RenderOptions{});
  ASSERT_FALSE(r.has_value());
  EXPECT_NE(r.error().to_string().find(bad_dir.string()), std::string::npos) << r.error().to_string();

  // An invalid model: the error names model.cao in the target directory, with a line number.
  const fs::path out = dir.path() / "seq";
  r = write_sequence(out.string(), "V1\n8\n0 0 0\n", default_camera(), traj, RenderOptions{});
  ASSERT_FALSE(r.has_value());
  EXPECT_NE(r.error().file.find("model.cao"), std::string::npos) << r.error().to_string();
  EXPECT_GT(r.error().line, 0);
  EXPECT_FALSE(fs::exists(out / "frames"));  // nothing written

  r = write_sequence(out.string(), box_cao(), default_camera(), {}, RenderOptions{});
  ASSERT_FALSE(r.has_value());
  EXPECT_NE(r.error().to_string().find(out.string()), std::string::npos) << r.error().to_string();
}

}  // namespace
}  // namespace v4r::synth
