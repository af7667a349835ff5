// v4r - robust model-based object tracking. MIT licence.
// ViSP's real cube sequence (visp-images-data) tracked without an initial pose (issue 10): the
// search finds the cube, and it must be `tracking` by frame 10 and never lost after, at ViSP's
// own tracker's pose (tests/data/visp_cube_reference.csv) modulo the cube's 24 symmetries.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "v4r/detection/symmetry.hpp"
#include "v4r/detection/template_set.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/tracker.hpp"
#include "visp_cube.hpp"
#include "visp_images.hpp"

using namespace v4r;
namespace fs = std::filesystem;

TEST(VispCubeSearch, FoundWithoutAnInitialPoseByFrameTenAndTrackedAfter) {
  const fs::path root = visp_images();
  V4R_NEED_VISP_IMAGES(root);
  VispCubeData cube;
  ASSERT_NO_FATAL_FAILURE(load_visp_cube(root, cube));
  const auto& model = cube.model;
  const detection::DetectorParams dp = cube.detector();
  auto ts = detection::build_templates(*model, cube.camera, dp);
  ASSERT_TRUE(ts) << ts.error().to_string();
  const auto sym = detection::model_symmetries(*model);

  pipeline::SingleObjectTracker tracker(model, cube.camera);
  tracker.enable_search(std::make_shared<const detection::TemplateSet>(std::move(*ts)), pipeline::ObjectSearchParams{},
                        dp);
  tracker.start_search();
  const std::vector<fs::path>& frames = cube.frames;
  int first = -1, not_tracking_after = 0, degraded_after = 0, far = 0;
  double worst_mm = 0.0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const cv::Mat grey = cv::imread(frames[k].string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(grey.empty()) << frames[k];
    const pipeline::FrameResult r = tracker.track(io::as_view(grey));
    const scene::TrackStatus s = r.report.status;
    if (first < 0) {
      if (r.search.searched)
        std::printf("[visp cube search] frame %zu: %d tried, best evidence %.2f%s\n", k, r.search.tried,
                    r.search.best_evidence, r.search.found ? " (candidate)" : "");
      if (s != scene::TrackStatus::kTracking) continue;
      first = static_cast<int>(k);
    }
    if (s == scene::TrackStatus::kDegraded) ++degraded_after;
    if (s == scene::TrackStatus::kLost || s == scene::TrackStatus::kSearching) ++not_tracking_after;
    const auto e = detection::symmetric_pose_error(r.T_cam_obj, cube.reference[k].T_cam_obj, sym);
    worst_mm = std::max(worst_mm, 1e3 * e.translation);
    if (e.translation > 0.05 || e.rotation > 15.0 * M_PI / 180.0) ++far;
  }
  std::printf("[visp cube search] tracking from frame %d; after it %d frames lost or searching, %d degraded, %d "
              "frames beyond 5 cm / 15 deg of ViSP's pose (worst %.1f mm)\n",
              first, not_tracking_after, degraded_after, far, worst_mm);
  ASSERT_GE(first, 0) << "never found";
  EXPECT_LE(first, 10);
  EXPECT_EQ(not_tracking_after, 0);
  EXPECT_EQ(far, 0);
}
