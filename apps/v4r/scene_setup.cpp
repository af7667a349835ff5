// v4r - robust model-based object tracking. MIT licence.
#include "scene_setup.hpp"

#include <fmt/format.h>

#include "app.hpp"
#include "plausibility.hpp"

namespace v4r::app {

Expected<SceneSetup> build_scene(const io::SceneFile& file, bool warnings) {
  SceneSetup s;
  for (const io::SceneCameraSpec& c : file.cameras)
    s.scene.add_camera(scene::Camera{c.name, c.calibration, c.T_ref_cam});
  for (const io::SceneObjectSpec& o : file.objects) {
    auto model = load_model(o.model_path, o.scale);
    if (!model) return o.model_at.error(fmt::format("the model does not load: {}", model.error().to_string()));
    if (warnings)
      for (auto& w : check_model_size(**model, o.model_path)) s.warnings.push_back(fmt::format("{}: {}", o.name, w));
    // `colour:` as --colour: every face of the model gets it (the detector's colour stage).
    auto added = s.scene.add_object(o.name, with_colour(*model, o.colour));
    if (!added) return o.at.error(added.error().message);
  }
  if (auto p = set_start_poses(file, s.scene); !p) return p.error();
  return s;
}

Expected<void> set_start_poses(const io::SceneFile& file, scene::Scene& scene) {
  for (std::size_t i = 0; i < file.objects.size(); ++i) {
    const io::SceneObjectSpec& o = file.objects[i];
    const long index = scene.find_object(o.name);
    if (index < 0) return o.at.error(fmt::format("object '{}' is not in the scene", o.name));
    if (o.init_pose) {
      scene.set_pose(static_cast<std::size_t>(index), *o.init_pose);
    } else {
      scene.start_search(static_cast<std::size_t>(index));  // found by the search (issue 10)
    }
  }
  return {};
}

}  // namespace v4r::app
