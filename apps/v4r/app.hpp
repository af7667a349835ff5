// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/model/model.hpp"
#include "v4r/pipeline/tracker.hpp"

namespace v4r::app {

/// Options shared by `v4r track` and `v4r demo`.
struct TrackOptions {
  std::string model_path, camera_path, input, output_csv, overlay, gt_csv;
  std::optional<geometry::SE3> init_pose;
  std::string init_pose_file;
  pipeline::CycleParams params;
  double fps = 30.0;        ///< frame rate of the input (time stamps for the filter); <= 0: default interval
  double mesh_scale = 1.0;  ///< file units -> metres for mesh models
  bool quiet = false;
};

/// Summary of a tracked sequence.
struct TrackSummary {
  int frames = 0;
  int lost = 0, degraded = 0;
  std::vector<geometry::SE3> poses;
  std::vector<double> cycle_ms, visibility_ms, track_ms, solve_ms;
  std::vector<int> features_used;
  std::vector<int> features_visible, features_found, junctions_used;  ///< per frame (v4r bench)
};

/// Loads a model by extension (.cao or a mesh). Errors name the file; accepted imperfections of a
/// .cao (faces slightly off their plane) go to `warnings` if given, else to the log.
Expected<std::shared_ptr<const model::Model>> load_model(const std::string& path, double mesh_scale = 1.0,
                                                         const model::CaoReadOptions& cao = {},
                                                         std::vector<Error>* warnings = nullptr);

/// Runs `v4r track`: loads inputs, tracks every frame, writes the CSV and the overlay.
Expected<TrackSummary> run_track(const TrackOptions& opt);

/// Prints the accuracy (if ground truth is given) and timing table of a tracked sequence.
void print_report(const TrackSummary& s, const std::vector<geometry::SE3>* truth);

int cmd_track(const TrackOptions& opt);

}  // namespace v4r::app
