// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>

#include "v4r/core/expected.hpp"
#include "v4r/model/model.hpp"

namespace v4r::model {

/// \brief Reads a ViSP `.cao` model (version V1): 3-D points, lines (with `name=`), faces from
/// lines, faces from points, cylinders, circles, `#` comments, and `load("file.cao", t=[...],
/// tu=[...])` includes (paths relative to the including file, cycles detected). Errors name
/// the file, line and column.
Expected<Model> load_cao(const std::string& path);

/// Parses `.cao` text; `source` names it in errors and is the base for relative includes.
Expected<Model> parse_cao(const std::string& text, const std::string& source);

}  // namespace v4r::model
