// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "v4r/core/expected.hpp"

namespace v4r::server {

/// \brief The folders of the server's file system that clients may name (`AddModel path=`,
/// `Log on file=`, `.cao` includes): the operator's choice (`--data-dir`, `--log-dir`).
///
/// A relative path is taken inside the first folder. Paths are resolved (`.`, `..`, symlinks)
/// before the check, so `../outside/x.cao` and a symlink inside a folder that points out of it are
/// refused. Refusals are errors whose field is the protocol code `forbidden`; the message names
/// the path as the client gave it, never what it resolved to. A default-constructed policy has no
/// folder and refuses everything. Immutable after creation: safe to share between threads.
class PathPolicy {
 public:
  PathPolicy() = default;
  /// Resolves `dirs` (each must be an existing folder). `option` names them in errors
  /// (e.g. "--data-dir").
  static Expected<PathPolicy> create(const std::vector<std::string>& dirs, std::string_view option);

  [[nodiscard]] bool empty() const { return roots_.empty(); }
  /// The resolved folders, in the order given.
  [[nodiscard]] const std::vector<std::filesystem::path>& roots() const { return roots_; }

  /// An existing file to read: its resolved path, inside one of the folders. Errors: `forbidden`
  /// (outside, or no folder), `io_error` (inside but not a regular file).
  [[nodiscard]] Expected<std::filesystem::path> resolve_read(const std::string& path) const;
  /// A file to create or overwrite: its folder must exist and resolve inside one of the folders,
  /// and the file must not be a symlink. Returns the path to open (with O_NOFOLLOW). Errors:
  /// `forbidden`, `io_error` (no such folder).
  [[nodiscard]] Expected<std::filesystem::path> resolve_write(const std::string& path) const;
  /// True when the resolved path `p` lies inside one of the folders (or is one).
  [[nodiscard]] bool contains(const std::filesystem::path& p) const;

 private:
  std::filesystem::path absolute(const std::string& path) const;
  std::vector<std::filesystem::path> roots_;
};

}  // namespace v4r::server
