// v4r - robust model-based object tracking. MIT licence.
#include "v4r/server/path_policy.hpp"

#include <fmt/format.h>

#include "v4r/protocol/protocol.hpp"

namespace v4r::server {

namespace fs = std::filesystem;

namespace {

Unexpected refuse(std::string_view code, std::string msg) {
  Error e{std::move(msg), {}, 0, 0, {}};
  e.field = std::string(code);
  return Unexpected{std::move(e)};
}

bool inside(const fs::path& p, const fs::path& root) {
  const fs::path rel = p.lexically_relative(root);
  if (rel.empty()) return false;
  const std::string first = rel.begin()->string();
  return first != "..";
}

}  // namespace

Expected<PathPolicy> PathPolicy::create(const std::vector<std::string>& dirs, std::string_view option) {
  PathPolicy p;
  for (const std::string& d : dirs) {
    std::error_code ec;
    const fs::path c = fs::canonical(d.empty() ? fs::path(".") : fs::path(d), ec);
    if (ec || !fs::is_directory(c, ec))
      return make_error(fmt::format("{} {}: not an existing folder", option, d));
    p.roots_.push_back(c);
  }
  return p;
}

fs::path PathPolicy::absolute(const std::string& path) const {
  const fs::path p(path);
  return p.is_absolute() ? p : roots_.front() / p;
}

bool PathPolicy::contains(const fs::path& p) const {
  for (const fs::path& r : roots_)
    if (inside(p, r)) return true;
  return false;
}

Expected<fs::path> PathPolicy::resolve_read(const std::string& path) const {
  if (roots_.empty() || path.empty())
    return refuse(protocol::code::kForbidden, fmt::format("{}: the server reads no files named by clients", path));
  std::error_code ec;
  // weakly_canonical resolves every symlink and `..` of the part that exists.
  const fs::path r = fs::weakly_canonical(absolute(path), ec);
  if (ec || !contains(r))
    return refuse(protocol::code::kForbidden, fmt::format("{}: outside the server's data folders", path));
  if (!fs::is_regular_file(r, ec)) return refuse(protocol::code::kIoError, fmt::format("{}: no such file", path));
  return r;
}

Expected<fs::path> PathPolicy::resolve_write(const std::string& path) const {
  if (roots_.empty() || path.empty())
    return refuse(protocol::code::kForbidden,
                  fmt::format("{}: the server writes no files named by clients (start it with --log-dir)", path));
  const fs::path a = absolute(path);
  const fs::path name = a.filename();
  if (name.empty() || name == "." || name == "..")
    return refuse(protocol::code::kForbidden, fmt::format("{}: not a file name", path));
  std::error_code ec;
  const fs::path dir = fs::weakly_canonical(a.parent_path(), ec);
  if (ec || !contains(dir))
    return refuse(protocol::code::kForbidden, fmt::format("{}: outside the server's log folders", path));
  if (!fs::is_directory(dir, ec)) return refuse(protocol::code::kIoError, fmt::format("{}: no such folder", path));
  const fs::path f = dir / name;
  if (fs::is_symlink(fs::symlink_status(f, ec)))
    return refuse(protocol::code::kForbidden, fmt::format("{}: a symlink; the server does not write through links", path));
  return f;
}

}  // namespace v4r::server
