// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>

#include "v4r/model/cao_reader.hpp"
#include "v4r/model/model.hpp"

namespace v4r::app {

/// A guess of the model file's units from its size in metres, for people ("metres",
/// "millimetres? ..."), and whether the size is plausible in metres.
std::string units_guess(double size_m, bool& plausible);

/// The text of `v4r inspect-model`: counts, extent, bounding box, units guess; with `verbose`
/// every face, line and circle.
std::string describe_model(const model::Model& m, bool verbose);

/// Runs `v4r inspect-model`: loads the model (scaled) and prints describe_model.
int cmd_inspect(const std::string& path, double scale, bool verbose, const model::CaoReadOptions& cao = {});

}  // namespace v4r::app
