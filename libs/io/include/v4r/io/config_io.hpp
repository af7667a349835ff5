// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>

#include "v4r/core/expected.hpp"
#include "v4r/core/params.hpp"

namespace v4r::io {

/// \brief Applies a YAML configuration file to a parameter registry: nested mappings name the
/// parameters (`track: {rows: 32}` sets `track.rows`). Unknown keys, values of the wrong type and
/// out-of-range values are errors naming the file, line, column and the dotted key. Parameters
/// not in the file keep their values. Nothing is changed when the file has an error.
Expected<void> apply_config_file(const std::string& path, ParamRegistry& registry);

/// Same for YAML text; `source` names it in errors.
Expected<void> apply_config_text(const std::string& text, const std::string& source, ParamRegistry& registry);

}  // namespace v4r::io
