// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include "v4r/core/params.hpp"
#include "v4r/pipeline/vision_cycle.hpp"

namespace v4r::pipeline {

/// \brief Binds every tunable parameter of the vision cycle to a dotted name with its range,
/// unit and meaning (for `--config` YAML files, `v4r config` and the server's SetParam). The
/// registry points into `p`, which must outlive it.
ParamRegistry make_registry(CycleParams& p);

}  // namespace v4r::pipeline
