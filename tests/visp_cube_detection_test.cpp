// v4r - robust model-based object tracking. MIT licence.
// Detection without an initial pose on real images: ViSP's cube sequence (visp-images-data),
// first frames, against ViSP's own tracker's trajectory (tests/data/visp_cube_reference.csv),
// modulo the cube's 24 symmetries (an edge detector cannot tell the faces of a cube apart).
#include <array>
#include <filesystem>
#include <memory>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "v4r/detection/detector.hpp"
#include "v4r/detection/symmetry.hpp"
#include "v4r/detection/template_cache.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/cao_reader.hpp"
#include "visp_cube.hpp"
#include "visp_images.hpp"

using namespace v4r;
namespace fs = std::filesystem;

TEST(VispCubeDetection, BestHypothesisOnTheFirstFramesIsTheRealCube) {
  const fs::path root = visp_images();
  V4R_NEED_VISP_IMAGES(root);
  VispCubeData cube;
  ASSERT_NO_FATAL_FAILURE(load_visp_cube(root, cube));
  const auto& model = cube.model;
  const detection::DetectorParams p = cube.detector();
  auto ts = detection::build_templates(*model, cube.camera, p);
  ASSERT_TRUE(ts) << ts.error().to_string();
  auto templates = std::make_shared<const detection::TemplateSet>(std::move(*ts));
  const auto sym = detection::model_symmetries(*model);
  EXPECT_EQ(sym.size(), 24u);
  detection::Detector det(model, templates, cube.camera, p);
  std::array<detection::Hypothesis, 16> hyp;
  // The best hypothesis (verified ones first, then by score) on each frame; verified or not.
  int found = 0, verified = 0;
  const int frames = 10;
  for (int k = 0; k < frames; ++k) {
    const fs::path& f = cube.frames[static_cast<std::size_t>(k)];
    const cv::Mat grey = cv::imread(f.string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(grey.empty()) << f;
    const auto r = det.detect(io::as_view(grey), hyp);
    ASSERT_EQ(r.status, detection::DetectionResult::Status::kOk);
    ASSERT_GT(r.hypotheses, 0);
    const auto e = detection::symmetric_pose_error(hyp[0].T_cam_obj, cube.reference[static_cast<std::size_t>(k)].T_cam_obj, sym);
    std::printf("frame %d: %.1f mm %.2f deg from ViSP's pose (score %.2f, %s)\n", k, 1e3 * e.translation,
                e.rotation * 180.0 / M_PI, hyp[0].verification.score, hyp[0].verified ? "verified" : "not verified");
    const bool close = e.translation <= 0.05 && e.rotation <= 5.0 * M_PI / 180.0;
    found += close ? 1 : 0;
    verified += close && hyp[0].verified ? 1 : 0;
    EXPECT_FALSE(hyp[0].verified && !close) << "frame " << k << ": a wrong pose verified";
  }
  EXPECT_GE(found, 8) << "of " << frames << " frames";
  // Not yet: the real cube's soft edges score 0.67..0.7 with the default verification (accept
  // 0.75, chosen for no false accepts on object-free images); issue 10 asks for it.
  std::printf("verified and right: %d of %d frames\n", verified, frames);
}
