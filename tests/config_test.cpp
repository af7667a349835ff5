// v4r - robust model-based object tracking. MIT licence.
// `v4r config` prints every parameter of the registry (the names `--set`, `SetParam` and the
// YAML files use), each with its value, and the numbers with their range (issue 13).
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "v4r/detection/detector_params.hpp"
#include "v4r/pipeline/object_search.hpp"
#include "v4r/pipeline/params.hpp"

namespace {

std::string run_config() {
  std::string out;
  FILE* p = ::popen(V4R_CLI " config", "r");
  if (!p) return out;
  char buf[4096];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  EXPECT_EQ(::pclose(p), 0);
  return out;
}

TEST(Config, PrintsEveryParameterOfTheRegistryWithItsRange) {
  const std::string out = run_config();
  ASSERT_FALSE(out.empty());
  // Nested YAML mappings (two spaces per level) -> dotted names of the leaves and their comments.
  std::map<std::string, std::string> printed;  // name -> the rest of the line after "key:"
  std::vector<std::string> path;
  std::size_t start = 0;
  while (start < out.size()) {
    std::size_t end = out.find('\n', start);
    if (end == std::string::npos) end = out.size();
    const std::string line = out.substr(start, end - start);
    start = end + 1;
    if (line.empty() || line.front() == '#') continue;
    const std::size_t indent = line.find_first_not_of(' ');
    const std::size_t colon = line.find(':', indent);
    ASSERT_NE(colon, std::string::npos) << line;
    ASSERT_EQ(indent % 2, 0u) << line;
    path.resize(indent / 2);
    const std::string key = line.substr(indent, colon - indent);
    const std::string rest = line.substr(colon + 1);
    if (rest.empty()) {
      path.push_back(key);
      continue;
    }
    std::string name;
    for (const std::string& p : path) name += p + ".";
    EXPECT_FALSE(printed.count(name + key)) << "printed twice: " << name + key;
    printed[name + key] = rest;
  }
  v4r::pipeline::CycleParams params;
  v4r::ParamRegistry reg = v4r::pipeline::make_registry(params);
  v4r::detection::DetectorParams detect_params;  // `v4r config` prints the detector's too
  v4r::detection::add_params(reg, detect_params);
  v4r::pipeline::ObjectSearchParams search_params;  // and the search's (issue 10)
  v4r::pipeline::add_search_params(reg, search_params);
  std::set<std::string> names;
  for (const v4r::ParamRegistry::Entry& e : reg.entries()) {
    names.insert(e.name);
    auto it = printed.find(e.name);
    if (it == printed.end()) {
      ADD_FAILURE() << "not printed: " << e.name;
      continue;
    }
    EXPECT_NE(it->second.find('#'), std::string::npos) << e.name << " has no documentation: " << it->second;
    if (!std::holds_alternative<bool*>(e.field)) {
      EXPECT_NE(it->second.find(" .. "), std::string::npos) << e.name << " has no range: " << it->second;
    }
  }
  for (const auto& [name, rest] : printed) EXPECT_TRUE(names.count(name)) << "printed but not a parameter: " << name;
  EXPECT_EQ(printed.size(), reg.entries().size());
  // Parameters that existed without a name before issue 13.
  for (const char* n : {"track.side_offset", "track.side_width", "track.chroma_min_sigma", "track.shadow_tolerance",
                        "track.learn_min_inlier_ratio", "ellipse.max_candidates_per_line", "ellipse.max_edge_angle",
                        "solver.min_observations", "solver.oblique_weighting", "solver.robust_max_iterations",
                        "solver.robust_step_tolerance", "solver.max_threshold_scale", "solver.degeneracy_ratio",
                        "solver.min_depth", "filter.init_velocity_sigma", "filter.init_angular_velocity_sigma",
                        "filter.reference_dt"})
    EXPECT_TRUE(printed.count(n)) << n;
}

}  // namespace
