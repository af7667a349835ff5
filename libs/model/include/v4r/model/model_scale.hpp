// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include "v4r/core/expected.hpp"
#include "v4r/model/model.hpp"

namespace v4r::model {

/// A copy of `m` with every length multiplied by `s` > 0 (junctions, circles, cylinders; e.g.
/// 0.001 for a model written in millimetres). Lines, faces and their adjacency are kept.
Expected<Model> scaled(const Model& m, double s);

}  // namespace v4r::model
