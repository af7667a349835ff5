// v4r - robust model-based object tracking. MIT licence.
#include "v4r/io/config_io.hpp"

#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

// GCC 12 reports a dangling pointer inside yaml-cpp 0.7's inlined Node accessors (node/impl.h), a
// known false positive of that header; it is silenced for this file only.
#pragma GCC diagnostic ignored "-Wdangling-pointer"

namespace v4r::io {

namespace {

struct Setting {
  std::string key, value;
  int line = 0, column = 0;
};

Expected<void> flatten(const YAML::Node& node, const std::string& prefix, const std::string& source,
                       std::vector<Setting>& out) {
  for (auto it = node.begin(); it != node.end(); ++it) {
    const YAML::Mark mark = it->first.Mark();
    const std::string key = prefix.empty() ? it->first.as<std::string>() : prefix + "." + it->first.as<std::string>();
    const YAML::Node& v = it->second;
    if (v.IsMap()) {
      auto r = flatten(v, key, source, out);
      if (!r) return r;
    } else if (v.IsScalar()) {
      out.push_back(Setting{key, v.Scalar(), v.Mark().line + 1, v.Mark().column + 1});
    } else {
      Error e{"expected a value or a mapping of parameters", source, mark.line + 1, mark.column + 1, key};
      return Unexpected{std::move(e)};
    }
  }
  return {};
}

}  // namespace

Expected<void> apply_config_text(const std::string& text, const std::string& source, ParamRegistry& registry) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& ex) {
    return Unexpected{Error{ex.msg, source, ex.mark.line + 1, ex.mark.column + 1, {}}};
  }
  if (root.IsNull()) return {};
  if (!root.IsMap()) return Unexpected{Error{"a configuration is a mapping of parameters", source, 1, 1, {}}};
  std::vector<Setting> settings;
  try {
    auto r = flatten(root, "", source, settings);
    if (!r) return r;
  } catch (const YAML::Exception& ex) {
    return Unexpected{Error{ex.msg, source, ex.mark.line + 1, ex.mark.column + 1, {}}};
  }
  // Validate everything on a copy of the values first: a file with an error changes nothing.
  std::vector<std::pair<const ParamRegistry::Entry*, std::string>> old;
  for (const Setting& s : settings) {
    const ParamRegistry::Entry* e = registry.find(s.key);
    if (e) old.emplace_back(e, ParamRegistry::format(*e));
    auto r = registry.set(s.key, s.value);
    if (!r) {
      for (auto& [entry, value] : old) (void)registry.set(entry->name, value);
      Error err = r.error();
      err.file = source;
      err.line = s.line;
      err.column = s.column;
      return Unexpected{std::move(err)};
    }
  }
  return {};
}

Expected<void> apply_config_file(const std::string& path, ParamRegistry& registry) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return Unexpected{Error{"cannot open configuration file", path, 0, 0, {}}};
  std::stringstream ss;
  ss << f.rdbuf();
  return apply_config_text(ss.str(), path, registry);
}

}  // namespace v4r::io
