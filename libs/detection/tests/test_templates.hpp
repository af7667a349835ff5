// v4r - robust model-based object tracking. MIT licence.
// Templates for the tests, built once per ctest run and shared by its test processes.
#pragma once

#include <memory>

#include "v4r/detection/template_cache.hpp"
#include "v4r/detection/template_set.hpp"

namespace v4r::detection::test {

/// The templates of (model, camera, params), as build_templates makes them, through the template
/// cache (load_or_build) in the folder V4R_TEST_TEMPLATE_CACHE of the build tree (defined for every
/// test target by CMake): ctest empties it before each run (the fixture test
/// `template_cache_reset`), and so does every new build of the detection library, so a set is built
/// once a run and loaded (well under a second) by every other test process that asks for it.
inline Expected<std::shared_ptr<const TemplateSet>> test_templates(const model::Model& model,
                                                                   const geometry::PinholeCamera& cam,
                                                                   const DetectorParams& p) {
  return load_or_build(model, cam, p, V4R_TEST_TEMPLATE_CACHE);
}

}  // namespace v4r::detection::test
