// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "v4r/core/expected.hpp"
#include "v4r/detection/detector_params.hpp"
#include "v4r/detection/template_set.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/model/model.hpp"

namespace v4r::detection {

/// The key of a template set: a 64-bit FNV-1a hash of the format version, the model's content
/// (every junction, line, face, arc and cylinder), the camera's focal lengths and every
/// parameter that changes the templates (view range and template sampling).
std::uint64_t template_key(const model::Model& model, const geometry::PinholeCamera& cam, const DetectorParams& p);

/// The default cache folder: $XDG_CACHE_HOME/v4r, else $HOME/.cache/v4r, else ./.v4r-cache.
std::string default_cache_dir();

/// The file of a key in a cache folder: `<dir>/templates-<16 hex digits>.v4rt`.
std::string cache_file(const std::string& dir, std::uint64_t key);

/// Writes a template set: a header (magic "V4RTPL\\0\\0", format version, key, payload size,
/// FNV-1a checksum of the payload) and the payload (little-endian). Written to a temporary file
/// beside `path` and renamed, so that a reader never sees half a file. Errors name the path.
Expected<void> write_templates(const std::string& path, const TemplateSet& set, std::uint64_t key);

/// Reads a template set written by write_templates and checks everything before trusting it:
/// magic, version, key (`expected_key`), size, checksum, and that every index in it is in range.
/// Errors name the path and say what is wrong (stale: other key or version; corrupt: size,
/// checksum or content).
Expected<TemplateSet> read_templates(const std::string& path, std::uint64_t expected_key);

/// \brief What load_or_build did.
struct CacheReport {
  std::string path;    ///< the cache file
  bool built = false;  ///< the templates were built (no usable cache file)
  std::string reason;  ///< why they were built: "no cache file", or the read error
  bool written = false;  ///< the new templates were written to the cache
  std::string write_error;  ///< why they could not be written (the templates are still returned)
};

/// Loads the templates of (model, camera, params) from the cache folder `dir` (empty: the
/// default), or builds them when there is no file or the file is stale or corrupt, and writes
/// them there (creating the folder). An unwritable cache is reported, not an error.
Expected<std::shared_ptr<const TemplateSet>> load_or_build(const model::Model& model, const geometry::PinholeCamera& cam,
                                                           const DetectorParams& p, const std::string& dir,
                                                           CacheReport* report = nullptr,
                                                           const BuildProgress& progress = {});

}  // namespace v4r::detection
