// v4r - robust model-based object tracking. MIT licence.
// A Scene built from a scene file: every camera with its T_ref_cam, every object with its model.
#pragma once

#include <string>
#include <vector>

#include "v4r/core/expected.hpp"
#include "v4r/io/scene_file.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::app {

/// \brief What build_scene made of a scene file: the Scene (cameras in file order, objects in
/// file order) and the plausibility warnings of its models and poses.
struct SceneSetup {
  scene::Scene scene;
  std::vector<std::string> warnings;
};

/// Builds the Scene of a scene file: loads every object's model (errors name the scene file's
/// line and field), adds the cameras with their T_ref_cam and sets the objects' start poses
/// (set_start_poses). `warnings`: run the plausibility check of the models' size.
Expected<SceneSetup> build_scene(const io::SceneFile& file, bool warnings);

/// Sets the start pose (T_ref_obj) of every object of `file` in `scene`; an object without
/// `init_pose` is `searching` (Scene::start_search): found in the images by the search.
Expected<void> set_start_poses(const io::SceneFile& file, scene::Scene& scene);

}  // namespace v4r::app
