// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <memory>
#include <string>
#include <string_view>

#include "v4r/core/expected.hpp"
#include "v4r/detection/template_cache.hpp"

namespace v4r::app {

/// The detector's templates of `model` for camera `cam`, read from the cache in `cache_dir` or
/// built (detection::load_or_build); when they were built, one line on stderr (unless `quiet`)
/// names `what` and where they were cached, or why not.
Expected<std::shared_ptr<const detection::TemplateSet>> templates_for(const model::Model& model,
                                                                      const geometry::PinholeCamera& cam,
                                                                      const detection::DetectorParams& dp,
                                                                      const std::string& cache_dir, bool quiet,
                                                                      std::string_view what);

}  // namespace v4r::app
