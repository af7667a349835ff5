// v4r - robust model-based object tracking. MIT licence.
// Real images and a model v4r did not make: ViSP's cube sequence (Debian visp-images-data,
// ViSP-images/mbt/cube, 218 frames of a hand-held camera around an 8.4 cm cube) and every .cao
// model of that package.
//
// The cube sequence has no ground truth: the reference is ViSP 3.5's own edge tracker's
// trajectory, tests/data/visp_cube_reference.csv (how it was produced: tests/data/README.md).
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
  std::vector<double> et_mm, er_deg;
  int lost = 0, first_lost = -1, worst_t_frame = -1, beyond = 0;
  double worst_t = -1.0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const cv::Mat grey = cv::imread(frames[k].string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(grey.empty()) << frames[k];
    const pipeline::FrameResult r = tracker.track(io::as_view(grey));
    if (k == 0) continue;  // the first frame starts from the perturbed pose
    const geometry::SE3& R = cube.reference[k].T_cam_obj;
    et_mm.push_back(1e3 * (r.T_cam_obj.translation() - R.translation()).norm());
    er_deg.push_back(rotation_deg(r.T_cam_obj.rotation(), R.rotation()));
    if (et_mm.back() > 10.0 || er_deg.back() > 4.0) ++beyond;
    if (et_mm.back() > worst_t) {
      worst_t = et_mm.back();
      worst_t_frame = static_cast<int>(k);
    }
    if (r.report.status == scene::TrackStatus::kLost) {
      ++lost;
      if (first_lost < 0) first_lost = static_cast<int>(k);
    }
  }
  const double t_med = median(et_mm), t_max = *std::max_element(et_mm.begin(), et_mm.end());
  const double r_med = median(er_deg), r_max = *std::max_element(er_deg.begin(), er_deg.end());
  std::printf("[visp cube] vs ViSP over frames 1-217: translation median %.2f mm, max %.2f mm (frame %d); rotation "
              "median %.2f deg, max %.2f deg; %d frames beyond 10 mm / 4 deg; %d frames lost (first %d)\n",
              t_med, t_max, worst_t_frame, r_med, r_max, beyond, lost, first_lost);
  RecordProperty("translation_median_mm", fmt::format("{:.3f}", t_med));
  RecordProperty("translation_max_mm", fmt::format("{:.3f}", t_max));
  RecordProperty("rotation_median_deg", fmt::format("{:.3f}", r_med));
  RecordProperty("rotation_max_deg", fmt::format("{:.3f}", r_max));
  RecordProperty("frames_beyond_10mm_4deg", beyond);
  EXPECT_EQ(lost, 0) << "first lost at frame " << first_lost;
  EXPECT_LE(t_med, 3.0);
  EXPECT_LE(r_med, 1.5);
  // Issue 8's target for the largest deviation is 10 mm / 4 degrees; v4r is not there yet (25 mm
  // / 9.3 degrees at frame 188, where ViSP's two trackers disagree or its edge trajectory jumps).
  // With the line windows alone (samples.enabled=false): 23 frames beyond it, 26.8 mm / 12.6 deg
  // at most; with the per-sample measurement beside them, 13-14 frames from eight perturbed starts.
  EXPECT_LE(beyond, 16);
  EXPECT_LE(t_max, 30.0);
  EXPECT_LE(r_max, 11.0);
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
