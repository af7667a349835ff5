// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <functional>
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

/// Decides which files `load(...)` may read (a server reads only inside its data folders): gets
/// the path an include resolves to and returns the path to read, or an error that becomes the
/// include's error (its field is kept).
using IncludeCheck = std::function<Expected<std::string>(const std::string& path)>;
/// As load_cao / parse_cao, with every include passed through `check` (empty: any file).
Expected<Model> load_cao(const std::string& path, const IncludeCheck& check);
Expected<Model> parse_cao(const std::string& text, const std::string& source, const IncludeCheck& check);

}  // namespace v4r::model
