// v4r - robust model-based object tracking. MIT licence.
#include "templates.hpp"

#include <cstdio>

#include <fmt/format.h>

namespace v4r::app {

Expected<std::shared_ptr<const detection::TemplateSet>> templates_for(const model::Model& model,
                                                                      const geometry::PinholeCamera& cam,
                                                                      const detection::DetectorParams& dp,
                                                                      const std::string& cache_dir, bool quiet,
                                                                      std::string_view what) {
  detection::CacheReport rep;
  auto ts = detection::load_or_build(model, cam, dp, cache_dir, &rep);
  if (ts && rep.built && !quiet)
    fmt::print(stderr, "v4r track: built the detector's templates{} ({}){}\n", what, rep.reason,
               rep.written ? ", cached in " + rep.path : ", not cached: " + rep.write_error);
  return ts;
}

}  // namespace v4r::app
