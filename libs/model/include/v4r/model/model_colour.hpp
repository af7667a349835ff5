// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "v4r/core/expected.hpp"
#include "v4r/model/model.hpp"

namespace v4r::model {

/// Parses a face colour `R,G,B`: three numbers in [0, 1], e.g. 0.2,0.6,0.1 (`--colour`, the
/// scene file's `colour:`). An error names `source` (the option or field) and the component at fault.
Expected<Eigen::Vector3f> parse_colour(std::string_view spec, const std::string& source);

/// A copy of `m` whose every face (and cylinder) has the colour `rgb` (RGB, each in [0, 1]),
/// replacing the colours it had: `--colour` on the command line, for models without one.
Model with_face_colour(const Model& m, const Eigen::Vector3f& rgb);

/// Area of a face (m^2): half the norm of the sum of its loop's edge cross products.
double face_area(const Model& m, const Face& f);

/// The colour covering most face area (faces with a colour attribute; equal colours summed), or
/// none when no face has one. The detector's colour stage searches for this colour.
std::optional<Eigen::Vector3f> dominant_face_colour(const Model& m);

}  // namespace v4r::model
