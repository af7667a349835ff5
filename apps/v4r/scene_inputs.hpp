// v4r - robust model-based object tracking. MIT licence.
// The inputs of a scene file's cameras (`v4r track --scene`, `v4r serve --scene`).
#pragma once

#include <memory>
#include <string_view>
#include <vector>

#include "v4r/core/expected.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/io/scene_file.hpp"

namespace v4r::app {

/// Opens every camera's input (one per camera, in file order) and checks that their lengths
/// agree when the inputs know them. Errors name the scene file's line and field; `command`
/// (e.g. "v4r track --scene") says who needs the inputs.
Expected<std::vector<std::unique_ptr<io::FrameSource>>> open_scene_inputs(const io::SceneFile& file,
                                                                          std::string_view command);

}  // namespace v4r::app
