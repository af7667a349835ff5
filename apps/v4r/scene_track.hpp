// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>
#include <vector>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/detection/detector_params.hpp"
#include "v4r/pipeline/object_search.hpp"
#include "v4r/pipeline/vision_cycle.hpp"

namespace v4r::app {

/// \brief Options of `v4r track --scene S.yaml --output-dir D`.
struct SceneTrackOptions {
  std::string scene_path;
  std::string output_dir;   ///< D/<object>.csv per object
  std::string overlay_dir;  ///< empty: none; else DIR/<camera>/NNNNNN.png per camera
  pipeline::CycleParams params;
  /// search.*: objects without init_pose, and lost ones, are searched for in camera 0's image with
  /// the detector's templates (detect.*, cached in cache_dir; default $XDG_CACHE_HOME/v4r).
  pipeline::ObjectSearchParams search;
  detection::DetectorParams detect;
  std::string cache_dir;
  double fps = 0.0;         ///< frame rate of the time stamps; 0: 1 / filter.frame_interval
  bool warnings = true;     ///< plausibility checks (model size, where each object lands in each camera)
  int progress = -1;        ///< progress line on stderr: 1 always, 0 never, -1 when stderr is a terminal
  bool quiet = false;
};

/// \brief What a scene track did: frames, the whole cycle's time per frame, per object its
/// poses (T_ref_obj) and how often it was lost or degraded.
struct SceneTrackSummary {
  struct ObjectSummary {
    std::string name;
    std::vector<geometry::SE3> poses;
    int lost = 0, degraded = 0, searching = 0;
  };
  int frames = 0;
  std::vector<std::string> cameras;
  std::vector<ObjectSummary> objects;
  std::vector<std::string> csv_paths;  ///< per object
  std::vector<double> cycle_ms;        ///< per frame, all cameras and objects (and the search)
  std::size_t warnings = 0;
};

/// Tracks every object of a scene file through the frames of all its cameras, taken in step
/// (frame k of every input): one vision cycle per frame over all cameras, one pose CSV per object
/// (poses.csv's columns, pose T_ref_obj, cycle_ms the whole cycle). Errors name the scene file's
/// line and field: inputs of unequal length, images that do not fit their calibration. Objects
/// without init_pose are searched for from frame 0 (their rows say `searching`, pose fields
/// empty, until found), lost ones again after search.lost_frames (pipeline::ObjectSearch).
Expected<SceneTrackSummary> run_scene_track(const SceneTrackOptions& opt);

/// `v4r track --scene`: runs it and prints a summary; 0, 1 (error) or 3 (an object lost or
/// searched on every frame).
int cmd_track_scene(const SceneTrackOptions& opt);

}  // namespace v4r::app
