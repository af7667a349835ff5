// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <memory>
#include <vector>

#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"
#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::app {

/// \brief A rendered scene for `v4r bench --cameras N --objects M`.
struct SceneCostInput {
  std::shared_ptr<const model::Model> model;
  geometry::PinholeCamera camera;
  std::vector<geometry::SE3> trajectory;  ///< T_ref_obj of the arrangement's centre, per frame
  synth::RenderOptions render;
  int cameras = 1;  ///< 1..4: camera 0 at the reference, then a 12 cm stereo partner toed in 5 deg, ...
  int objects = 1;  ///< 1..4 copies of the model side by side (a row of two, a 2x2 grid)
  int repeat = 5;
  double budget_ms = 0.0;
  pipeline::CycleParams params;  ///< the cycle's parameters (--config, --set); budget and threads from above
  int threads = 1;  ///< > 1: the cycle over all is also run on this many threads (cycle.threads)
};

/// Renders every camera's images of the arrangement and runs one vision cycle per frame over
/// all cameras and objects, then the same images with camera 0 and object 0 alone; prints the
/// median cycle of both, their ratio (the cost of the extra cameras or objects) and the accuracy
/// of object 0 in both runs. Returns the exit code.
int run_scene_cost(const SceneCostInput& in);

}  // namespace v4r::app
