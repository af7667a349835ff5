// v4r - robust model-based object tracking. MIT licence.
// Real images and a model v4r did not make: ViSP's cube sequence (Debian visp-images-data,
// ViSP-images/mbt/cube, 218 frames of a hand-held camera around an 8.4 cm cube) and every .cao
// model of that package.
//
// The cube sequence has no ground truth: the references are ViSP 3.5's own trajectories, of its
// edge tracker (tests/data/visp_cube_reference.csv) and of its hybrid edge and KLT tracker
// (tests/data/visp_cube_klt_reference.csv); how they were produced: tests/data/README.md.
//
// Without the package the tests skip, unless V4R_REQUIRE_VISP_IMAGES is set (`make test` sets it
// and installs the package), in which case they fail.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "v4r/io/camera_io.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/tracker.hpp"
#include "visp_cube.hpp"
#include "visp_images.hpp"

using namespace v4r;
namespace fs = std::filesystem;

namespace {

double rotation_deg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const double c = std::clamp(((a.transpose() * b).trace() - 1.0) / 2.0, -1.0, 1.0);
  return std::acos(c) * 180.0 / M_PI;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// A unit vector from a fixed-seed mt19937 (whose output sequence the C++ standard fixes).
Eigen::Vector3d unit_vector(std::mt19937& g) {
  Eigen::Vector3d v;
  do {
    for (int k = 0; k < 3; ++k) v[k] = 2.0 * (static_cast<double>(g()) / 4294967296.0) - 1.0;
  } while (v.norm() < 0.1 || v.norm() > 1.0);
  return v.normalized();
}

/// How far v4r's poses of frames 1-217 are from one of ViSP's trajectories (printed).
struct Deviation {
  double t_med = 0.0, t_max = 0.0, r_med = 0.0, r_max = 0.0;  // mm, deg
  int beyond = 0;                                              // frames beyond 10 mm or 4 deg
  std::vector<std::uint8_t> beyond_at;                         // per frame 1-217: beyond
};

Deviation deviation(const std::vector<geometry::SE3>& poses, const std::vector<io::PoseRow>& reference, const char* name) {
  std::vector<double> et_mm, er_deg;
  Deviation d;
  int worst_t_frame = 0, worst_r_frame = 0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const geometry::SE3& R = reference[i + 1].T_cam_obj;
    et_mm.push_back(1e3 * (poses[i].translation() - R.translation()).norm());
    er_deg.push_back(rotation_deg(poses[i].rotation(), R.rotation()));
    const bool beyond = et_mm.back() > 10.0 || er_deg.back() > 4.0;
    d.beyond += beyond ? 1 : 0;
    d.beyond_at.push_back(beyond ? 1 : 0);
    if (et_mm.back() > d.t_max) {
      d.t_max = et_mm.back();
      worst_t_frame = static_cast<int>(i + 1);
    }
    if (er_deg.back() > d.r_max) {
      d.r_max = er_deg.back();
      worst_r_frame = static_cast<int>(i + 1);
    }
  }
  d.t_med = median(et_mm);
  d.r_med = median(er_deg);
  std::printf("[visp cube] vs %s over frames 1-217: translation median %.2f mm, max %.2f mm (frame %d); rotation "
              "median %.2f deg, max %.2f deg (frame %d); %d frames beyond 10 mm / 4 deg\n",
              name, d.t_med, d.t_max, worst_t_frame, d.r_med, d.r_max, worst_r_frame, d.beyond);
  return d;
}

}  // namespace

TEST(VispCube, TracksTheRealCubeFromAPerturbedStartLikeViSP) {
  const fs::path root = visp_images();
  V4R_NEED_VISP_IMAGES(root);
  VispCubeData cube;
  ASSERT_NO_FATAL_FAILURE(load_visp_cube(root, cube));
  const fs::path& mbt = cube.mbt;
  const auto& model = cube.model;
  auto start = io::load_pose_file((mbt / "cube.0.pos").string());
  ASSERT_TRUE(start) << start.error().to_string();

  const std::vector<fs::path>& frames = cube.frames;
  ASSERT_EQ(frames.size(), 218u);

  // Start 1 cm and 3 degrees off ViSP's start pose (fixed seed): translation along a random
  // direction, rotation about a random axis through the object's origin.
  std::mt19937 g(20261201u);
  const Eigen::Vector3d dt = 0.01 * unit_vector(g);
  const Eigen::Vector3d dw = (3.0 * M_PI / 180.0) * unit_vector(g);
  const geometry::SE3 T0 = *start;
  const geometry::SE3 T0_perturbed(Eigen::Matrix3d(geometry::so3_exp(dw) * T0.rotation()), T0.translation() + dt);

  pipeline::SingleObjectTracker tracker(model, cube.camera);
  tracker.set_pose(T0_perturbed);
  std::vector<geometry::SE3> poses;  // frames 1-217
  int lost = 0, first_lost = -1;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const cv::Mat grey = cv::imread(frames[k].string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(grey.empty()) << frames[k];
    const pipeline::FrameResult r = tracker.track(io::as_view(grey));
    if (k == 0) continue;  // the first frame starts from the perturbed pose
    poses.push_back(r.T_cam_obj);
    if (r.report.status == scene::TrackStatus::kLost) {
      ++lost;
      if (first_lost < 0) first_lost = static_cast<int>(k);
    }
  }
  const Deviation edge = deviation(poses, cube.reference, "ViSP's edge tracker");
  const Deviation hybrid = deviation(poses, cube.hybrid_reference, "ViSP's edge and KLT tracker");
  int beyond_both = 0;  // frames beyond 10 mm / 4 deg of both of ViSP's trajectories
  for (std::size_t i = 0; i < edge.beyond_at.size(); ++i) beyond_both += edge.beyond_at[i] && hybrid.beyond_at[i] ? 1 : 0;
  std::printf("[visp cube] %d frames lost (first %d); %d frames beyond 10 mm / 4 deg of both trajectories\n", lost,
              first_lost, beyond_both);
  RecordProperty("translation_median_mm", fmt::format("{:.3f}", edge.t_med));
  RecordProperty("translation_max_mm", fmt::format("{:.3f}", edge.t_max));
  RecordProperty("rotation_median_deg", fmt::format("{:.3f}", edge.r_med));
  RecordProperty("rotation_max_deg", fmt::format("{:.3f}", edge.r_max));
  RecordProperty("frames_beyond_10mm_4deg", edge.beyond);
  RecordProperty("hybrid_translation_max_mm", fmt::format("{:.3f}", hybrid.t_max));
  RecordProperty("hybrid_rotation_max_deg", fmt::format("{:.3f}", hybrid.r_max));
  RecordProperty("hybrid_frames_beyond_10mm_4deg", hybrid.beyond);
  RecordProperty("frames_beyond_both", beyond_both);
  EXPECT_EQ(lost, 0) << "first lost at frame " << first_lost;
  EXPECT_LE(edge.t_med, 3.0);
  EXPECT_LE(edge.r_med, 1.5);
  // Issue 8's target for the largest deviation is 10 mm / 4 degrees; against ViSP's edge
  // trajectory v4r is not there (25 mm / 9.3 degrees at frame 188). With the line windows alone
  // (samples.enabled=false): 23 frames beyond it, 26.8 mm / 12.6 deg at most; with the per-sample
  // measurement beside them, 13-14 frames from 24 perturbed starts; since a grazing face's hidden
  // edges no longer crowd the silhouette out of the cycle (ViewPredictor::mark_ambiguous), 10 from
  // this start and 10.9 on average over 72 perturbed starts (10-23).
  EXPECT_LE(edge.beyond, 13);
  EXPECT_LE(edge.t_max, 30.0);
  EXPECT_LE(edge.r_max, 11.0);
  // ViSP's two trackers differ by up to 24.8 mm / 9.8 degrees (18 frames beyond 10 mm / 4 degrees,
  // 184-189 among them; tests/data/README.md). Against its hybrid trajectory, which also follows
  // the texture's points, v4r is beyond 10 mm / 4 degrees in 1 frame from this start (frame 184,
  // 4.6 degrees, where it is within 2 degrees of the edge trajectory); 1.8 frames on average over
  // 72 perturbed starts, 2.7 before the grazing-edge change (175-176, where one face is seen
  // nearly frontally and its turn is hardly observable). Beyond both trajectories at once: none
  // from this start, 0.74 frames on average over the 72 starts (2 of them 11 and 13 frames; in
  // the one examined, the top-front crease jumps onto a band printed on the top face at frame
  // 171), 2.0 before (175-176 from every start).
  EXPECT_LE(beyond_both, 1);
  EXPECT_LE(hybrid.t_med, 3.0);
  EXPECT_LE(hybrid.r_med, 1.5);
  EXPECT_LE(hybrid.beyond, 3);
  EXPECT_LE(hybrid.t_max, 12.0);
  EXPECT_LE(hybrid.r_max, 5.0);
}

TEST(VispCube, EveryCaoModelOfVispImagesLoads) {
  const fs::path root = visp_images();
  V4R_NEED_VISP_IMAGES(root);
  std::vector<fs::path> files;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file() && e.path().extension() == ".cao") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  ASSERT_GE(files.size(), 10u) << "expected ViSP's .cao models under " << root;
  int failed = 0;
  for (const fs::path& f : files) {
    std::vector<Error> warnings;
    auto m = model::load_cao(f.string(), {}, &warnings);
    if (!m) {
      ++failed;
      ADD_FAILURE() << m.error().to_string();
      continue;
    }
    std::printf("[visp cao] %s: %zu junctions, %zu lines, %zu arcs, %zu faces, %zu warnings\n",
                fs::relative(f, root).c_str(), m->junctions().size(), m->lines().size(), m->arcs().size(),
                m->faces().size(), warnings.size());
    for (const Error& w : warnings) std::printf("  warning: %s\n", w.to_string().c_str());
  }
  std::printf("[visp cao] %zu files, %d refused\n", files.size(), failed);
}
