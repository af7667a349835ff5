// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "v4r/core/expected.hpp"
#include "v4r/detection/tag_spec.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/io/pose_io.hpp"

namespace v4r::io {

/// \brief Where a value of the scene file stands, for the errors of later stages (a model that
/// does not load, inputs of unequal length): the scene file, 1-based line, and the field.
struct SceneFileMark {
  std::string file;
  int line = 0;
  std::string field;  ///< e.g. "cameras[1].input"

  /// An error at this place.
  [[nodiscard]] Error error(std::string message) const { return Error{std::move(message), file, line, 0, field}; }
};

/// \brief A camera of a scene file: its calibration (already loaded), its input and its pose in
/// the reference frame.
struct SceneCameraSpec {
  std::string name;
  std::string calibration_path;          ///< resolved against the scene file's folder
  geometry::PinholeCamera calibration;   ///< width = height = 0 when the file gives no image size
  std::string input;                     ///< folder, printf pattern, video or live camera; resolved like a path
  geometry::SE3 T_ref_cam;               ///< camera -> reference frame; identity when not given
  SceneFileMark at, input_at;            ///< the entry and its `input` field
};

/// \brief An object of a scene file: its model file and units, and optionally its start pose.
struct SceneObjectSpec {
  std::string name;
  std::string model_path;                ///< .cao or mesh, resolved against the scene file's folder
  double scale = 1.0;                    ///< model units -> metres (mesh_scale or model_units)
  std::optional<geometry::SE3> init_pose;  ///< T_ref_obj; nothing: the object must be found first
  std::optional<PoseNumbers> init_numbers;  ///< init_pose as written (for plausibility checks)
  /// `tag: "family:id:size_m:tx ty tz rx ry rz"` (as `--tag`): an AprilTag on the object that
  /// starts its search (camera 0).
  std::optional<detection::TagSpec> tag;
  /// `colour: [R, G, B]` (0..1, as `--colour`): every face of the model gets it.
  std::optional<Eigen::Vector3f> colour;
  SceneFileMark at, model_at, tag_at;    ///< the entry, its `model` field and its `tag` field
};

/// \brief A multi-camera, multi-object set-up as read from a scene file (YAML):
///
///     reference_frame: rig          # optional name of the reference frame (default "ref")
///     cameras:
///       - name: left
///         calibration: left.yaml    # OpenCV or ROS camera_info YAML (io::load_camera)
///         input: frames_left        # folder, printf pattern, video, /dev/videoN, gst:..., ros2:...
///         T_ref_cam: [0, 0, 0, 0, 0, 0]   # tx ty tz (m) rx ry rz (rad, Rodrigues); optional
///     objects:
///       - name: part
///         model: part.cao           # or a mesh (.obj, .ply, .stl)
///         mesh_scale: 0.001         # optional, or model_units: mm | cm | m
///         init_pose: [0.05, 0.1, 0.6, 2.0, 0.1, -0.5]   # T_ref_obj; optional
///         tag: "tag36h11:0:0.08:0 0 0.05 3.14159 0 0"   # optional, as --tag
///         colour: [0.2, 0.6, 0.1]   # optional, as --colour (RGB, 0..1)
///
/// Relative paths are taken relative to the scene file's folder. `input` is optional (the server
/// takes its images elsewhere), `objects` too; at least one camera is required.
struct SceneFile {
  std::string path;             ///< the scene file as given
  std::string reference_frame = "ref";
  std::vector<SceneCameraSpec> cameras;
  std::vector<SceneObjectSpec> objects;
  SceneFileMark objects_at;     ///< the `objects` key, or the file's first line without one
};

/// Loads a scene file; every error names the file, the line and the field (unknown key, missing
/// file, bad pose, duplicate name, a name that is no plain file name, no camera, a calibration
/// that does not load).
Expected<SceneFile> load_scene_file(const std::string& path);

/// Parses scene-file text; `source` names it in errors and `base_dir` resolves relative paths.
Expected<SceneFile> parse_scene_file(const std::string& text, const std::string& source, const std::string& base_dir);

}  // namespace v4r::io
