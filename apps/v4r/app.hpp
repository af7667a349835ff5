// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/model.hpp"
#include "v4r/pipeline/tracker.hpp"

namespace v4r::app {

/// The model's units as the user gives them: `--mesh-scale S` or `--model-units mm|cm|m`.
struct ModelUnitsArgs {
  double mesh_scale = 1.0;
  bool mesh_scale_given = false;
  std::string units;  ///< empty: not given
};

/// Options shared by `v4r track` and `v4r demo`.
struct TrackOptions {
  std::string model_path, camera_path, input, output_csv, overlay, gt_csv;
  std::optional<io::PoseNumbers> init_pose;  ///< --init-pose as given
  std::string init_pose_file;
  std::optional<detection::TagSpec> tag;  ///< --tag: an AprilTag on the object for the search
  pipeline::CycleParams params;
  detection::DetectorParams detect;    ///< detect.*: the search's templates and detector
  pipeline::ObjectSearchParams search;  ///< search.*: when and how the object is searched for
  std::string cache_dir;               ///< template cache folder (empty: the default)
  std::optional<Eigen::Vector3f> colour;  ///< --colour: every face of the model gets this colour (RGB 0..1)
  double fps = 0.0;          ///< frame rate given by --fps; 0: the video's own rate, else filter.frame_interval
  bool file_times = false;   ///< time stamps from the image files' modification times
  double mesh_scale = 1.0;   ///< model units -> metres
  bool warnings = true;      ///< plausibility checks of the inputs (--no-warnings turns them off)
  int progress = -1;         ///< progress line on stderr: 1 always, 0 never, -1 when stderr is a terminal
  bool quiet = false;
};

/// Summary of a tracked sequence.
struct TrackSummary {
  int frames = 0;
  int lost = 0, degraded = 0;
  int searching = 0;        ///< frames the object was searched for (no pose)
  int first_tracking = -1;  ///< first frame reported `tracking` (-1: none)
  std::vector<double> search_ms;  ///< per frame the search ran
  std::vector<geometry::SE3> poses;
  std::vector<double> cycle_ms, visibility_ms, track_ms, solve_ms;
  std::vector<int> features_used;
  std::vector<int> features_visible, features_found, junctions_used;  ///< per frame (v4r bench)
  double fps = 0.0;        ///< frame rate of the time stamps (0: file times)
  std::string timing;      ///< where the time stamps came from
  std::size_t warnings = 0;  ///< plausibility warnings printed
  std::int64_t dropped = 0;  ///< live input: frames dropped because a newer one came first
};

/// The .cao text of a built-in model (box, ship, flange, section, sponge), or nothing.
std::optional<std::string> builtin_model_text(const std::string& name);

/// True for the mesh extensions read through assimp (.obj, .ply, .stl, ...).
bool is_mesh_path(const std::string& path);

/// mm -> 0.001, cm -> 0.01, m -> 1; anything else is an error naming --model-units.
Expected<double> units_scale(const std::string& units);

/// The scale of --mesh-scale / --model-units (an error when both are given and disagree).
Expected<double> model_scale(const ModelUnitsArgs& a);

/// Loads a model: a built-in name (box, ship, flange, section, sponge), a .cao file or a mesh (.obj,
/// .ply, .stl, ...); every length is multiplied by `scale` (file units -> metres). Errors name
/// the file. Accepted imperfections of a .cao (faces slightly off their plane) go to `warnings`
/// if given, else to the log.
Expected<std::shared_ptr<const model::Model>> load_model(const std::string& path, double scale = 1.0,
                                                         const model::CaoReadOptions& cao = {},
                                                         std::vector<Error>* warnings = nullptr);

/// The model with every face coloured `colour` (when given): `--colour` for models without a
/// face colour, searched by the detector's colour stage.
std::shared_ptr<const model::Model> with_colour(std::shared_ptr<const model::Model> m, const std::optional<Eigen::Vector3f>& colour);

/// Runs `v4r track`: loads inputs, tracks every frame, writes the CSV and the overlay.
Expected<TrackSummary> run_track(const TrackOptions& opt);

/// Prints the accuracy (if ground truth is given) and timing table of a tracked sequence.
void print_report(const TrackSummary& s, const std::vector<geometry::SE3>* truth);

int cmd_track(const TrackOptions& opt);

}  // namespace v4r::app
