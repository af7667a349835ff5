// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief What one cycle did for one object.
struct ObjectReport {
  scene::TrackStatus status = scene::TrackStatus::kUninitialised;
  int features_visible = 0;
  int features_found = 0;
  int features_used = 0;   ///< observations kept by the pose solve (lines, ellipse points, junctions)
  int outliers = 0;
  int lines_used = 0, circle_points_used = 0, junctions_used = 0;
  int tangent_junctions = 0;  ///< line-arc junctions with a common tangent observed (in junctions_used when inliers)
  double rms_px = 0.0;
  double quality = 0.0;
  double evidence = 0.0;   ///< share of the projected model's edge samples confirmed by the image
  int evidence_samples = 0;
  int iterations = 0;
  int search_level = 0;    ///< 0: normal windows; > 0 searching wider after a bad frame
  bool measurement_rejected = false;  ///< the solve was refused by the filter gate
  bool prior_used = false;  ///< some directions were held by the prediction (partial observability)
  /// The per-sample measurement this frame (CycleParams::samples): not run (no doubt, or the image
  /// confirmed the line solve's pose well), run with the line solve's pose kept, or its pose kept.
  enum class SampleFit : std::uint8_t { kNotRun, kRun, kKept };
  SampleFit sample_fit = SampleFit::kNotRun;
  /// The object's cycle threw: the object was taken out of tracking (status kUninitialised, so
  /// later cycles skip it until its pose is set again); `error` says what was thrown.
  bool failed = false;
  std::string error;
};

/// \brief Per-cycle report: per-stage times, budget state and one ObjectReport per object.
struct CycleReport {
  std::int64_t frame = 0;
  double stamp_s = 0.0;
  double cycle_ms = 0.0;
  double visibility_ms = 0.0;  ///< prediction, visibility, projection, ambiguity
  double track_ms = 0.0;       ///< feature search and tracking
  double solve_ms = 0.0;       ///< pose estimation, view fusion and filter
  int degrade_level = 0;       ///< 0 none, 1 fewer samples, 2 features left out
  int features_dropped = 0;    ///< left out by the budget this cycle
  int windows = 0;             ///< feature windows measured (tracking and search, every pass)
  std::int64_t overruns = 0;   ///< cycles so far that took longer than the budget
  std::vector<ObjectReport> objects;
};

}  // namespace v4r::pipeline
