// v4r - robust model-based object tracking. MIT licence.
// ViSP's cube sequence (visp-images-data: ViSP-images/mbt/cube) as the tests use it: the model,
// the camera, two of ViSP's own trajectories (tests/data/visp_cube_*reference.csv) and the frames.
#pragma once

#include <algorithm>
#include <filesystem>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "v4r/detection/detector_params.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/cao_reader.hpp"

namespace {

struct VispCubeData {
  std::filesystem::path mbt;  ///< ViSP-images/mbt
  std::shared_ptr<const v4r::model::Model> model;
  v4r::geometry::PinholeCamera camera;
  std::vector<v4r::io::PoseRow> reference;  ///< one row per frame: ViSP's edge tracker
  /// One row per frame: ViSP's hybrid tracker (moving edges and KLT points on the faces' texture).
  std::vector<v4r::io::PoseRow> hybrid_reference;
  std::vector<std::filesystem::path> frames;  ///< image0000.pgm ... in order

  /// The detector's parameters for it: the default view range, distances 0.3..0.8 m (the
  /// hand-held camera is 0.45..0.6 m away).
  [[nodiscard]] v4r::detection::DetectorParams detector() const {
    v4r::detection::DetectorParams p;
    p.views.distance_min_m = 0.3;
    p.views.distance_max_m = 0.8;
    return p;
  }
};

/// Loads the cube from ViSP-images at `root`; what fails is a test failure (call it inside
/// ASSERT_NO_FATAL_FAILURE).
inline void load_visp_cube(const std::filesystem::path& root, VispCubeData& out) {
  out.mbt = root / "mbt";
  auto m = v4r::model::load_cao((out.mbt / "cube.cao").string());
  ASSERT_TRUE(m) << m.error().to_string();
  out.model = std::make_shared<const v4r::model::Model>(std::move(*m));
  auto cam = v4r::io::load_camera(V4R_TEST_DATA_DIR "/visp_cube_camera.yaml");
  ASSERT_TRUE(cam) << cam.error().to_string();
  out.camera = *cam;
  auto ref = v4r::io::load_pose_csv(V4R_TEST_DATA_DIR "/visp_cube_reference.csv");
  ASSERT_TRUE(ref) << ref.error().to_string();
  out.reference = std::move(*ref);
  auto hybrid = v4r::io::load_pose_csv(V4R_TEST_DATA_DIR "/visp_cube_klt_reference.csv");
  ASSERT_TRUE(hybrid) << hybrid.error().to_string();
  out.hybrid_reference = std::move(*hybrid);
  out.frames.clear();
  for (const auto& e : std::filesystem::directory_iterator(out.mbt / "cube"))
    if (e.path().extension() == ".pgm") out.frames.push_back(e.path());
  std::sort(out.frames.begin(), out.frames.end());
  ASSERT_EQ(out.frames.size(), out.reference.size());
  ASSERT_EQ(out.frames.size(), out.hybrid_reference.size());
}

}  // namespace
