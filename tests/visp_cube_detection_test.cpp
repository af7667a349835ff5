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
#include "visp_images.hpp"

using namespace v4r;
namespace fs = std::filesystem;

TEST(VispCubeDetection, BestHypothesisOnTheFirstFramesIsTheRealCube) {
  const fs::path root = visp_images();
  V4R_NEED_VISP_IMAGES(root);
  const fs::path mbt = root / "mbt";
  auto m = model::load_cao((mbt / "cube.cao").string());
  ASSERT_TRUE(m) << m.error().to_string();
  auto model = std::make_shared<const model::Model>(std::move(*m));
  auto cam = io::load_camera(V4R_TEST_DATA_DIR "/visp_cube_camera.yaml");
  ASSERT_TRUE(cam) << cam.error().to_string();
  auto ref = io::load_pose_csv(V4R_TEST_DATA_DIR "/visp_cube_reference.csv");
  ASSERT_TRUE(ref) << ref.error().to_string();

  detection::DetectorParams p;  // default view range; the hand-held camera is 0.45..0.6 m away
  p.views.distance_min_m = 0.3;
  p.views.distance_max_m = 0.8;
  auto ts = detection::build_templates(*model, *cam, p);
  ASSERT_TRUE(ts) << ts.error().to_string();
  auto templates = std::make_shared<const detection::TemplateSet>(std::move(*ts));
  const auto sym = detection::model_symmetries(*model);
  EXPECT_EQ(sym.size(), 24u);
  detection::Detector det(model, templates, *cam, p);
  std::array<detection::Hypothesis, 16> hyp;
  // The best hypothesis (verified ones first, then by score) on each frame; verified or not.
  int found = 0, verified = 0;
  const int frames = 10;
  for (int k = 0; k < frames; ++k) {
    const fs::path f = mbt / "cube" / fmt::format("image{:04d}.pgm", k);
    const cv::Mat grey = cv::imread(f.string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(grey.empty()) << f;
    const auto r = det.detect(io::as_view(grey), hyp);
    ASSERT_EQ(r.status, detection::DetectionResult::Status::kOk);
    ASSERT_GT(r.hypotheses, 0);
    const auto e = detection::symmetric_pose_error(hyp[0].T_cam_obj, (*ref)[static_cast<std::size_t>(k)].T_cam_obj, sym);
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
