// v4r - robust model-based object tracking. MIT licence.
#include "scene_inputs.hpp"

#include <fmt/format.h>

namespace v4r::app {

Expected<std::vector<std::unique_ptr<io::FrameSource>>> open_scene_inputs(const io::SceneFile& file,
                                                                          std::string_view command) {
  std::vector<std::unique_ptr<io::FrameSource>> inputs(file.cameras.size());
  for (std::size_t c = 0; c < file.cameras.size(); ++c) {
    const io::SceneCameraSpec& cam = file.cameras[c];
    if (cam.input.empty())
      return cam.at.error(fmt::format("camera '{}' has no input: `{}` reads every camera's frames "
                                      "(input: folder, printf pattern or video)",
                                      cam.name, command));
    auto src = io::FrameSource::open(cam.input);
    if (!src) return cam.input_at.error(fmt::format("the input does not open: {}", src.error().to_string()));
    inputs[c] = std::move(*src);
  }
  for (std::size_t c = 1; c < inputs.size(); ++c) {
    const int n0 = inputs[0]->size_hint(), n = inputs[c]->size_hint();
    if (n0 >= 0 && n >= 0 && n != n0)
      return file.cameras[c].input_at.error(fmt::format(
          "camera '{}' has {} frames but camera '{}' has {} ({}:{}): the cameras' frames are taken in step, their "
          "inputs must be of equal length",
          file.cameras[c].name, n, file.cameras[0].name, n0, file.path, file.cameras[0].input_at.line));
  }
  return inputs;
}

}  // namespace v4r::app
