// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "v4r/core/expected.hpp"
#include "v4r/model/model.hpp"

namespace v4r::model {

/// Decides which files `load(...)` may read (a server reads only inside its data folders): gets
/// the path an include resolves to and returns the path to read, or an error that becomes the
/// include's error (its field is kept).
using IncludeCheck = std::function<Expected<std::string>(const std::string& path)>;

/// \brief Options of the `.cao` reader.
struct CaoReadOptions {
  /// Largest distance of a face's point from the face's least-squares plane, as a fraction of the
  /// face's diameter (largest distance between two of its points), in [0, 1]. CAD exports and
  /// hand-measured models are rarely exactly planar: a face whose points lie off its plane by more
  /// than max(0.1 mm, 0.1 % of its diameter) but within this bound is accepted (with the
  /// least-squares plane's normal) and reported by one warning naming file:line and the offset;
  /// beyond it the face is refused (error with file:line:column).
  double max_off_plane = 0.10;
  /// Every include is passed through this check (empty: any file may be read).
  IncludeCheck include_check;
};

/// \brief Reads a ViSP `.cao` model (version V1): 3-D points, lines (with `name=`), faces from
/// lines, faces from points, cylinders, circles, `#` comments, and `load("file.cao", t=[...],
/// tu=[...])` includes (paths relative to the including file, cycles detected). Errors name
/// the file, line and column. Accepted imperfections (see CaoReadOptions) are appended to
/// `warnings` as Errors with file, line and column; without a list they are logged (V4R_LOG_WARN).
Expected<Model> load_cao(const std::string& path, const CaoReadOptions& options = {},
                         std::vector<Error>* warnings = nullptr);

/// Parses `.cao` text; `source` names it in errors and is the base for relative includes.
Expected<Model> parse_cao(const std::string& text, const std::string& source, const CaoReadOptions& options = {},
                          std::vector<Error>* warnings = nullptr);

}  // namespace v4r::model
