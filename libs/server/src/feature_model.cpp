// v4r - robust model-based object tracking. MIT licence.
#include "v4r/server/feature_model.hpp"

#include <algorithm>
#include <cmath>
#include <string_view>
#include <unordered_map>

#include <Eigen/Geometry>
#include <fmt/format.h>

namespace v4r::server {

namespace {

Unexpected fail(const char* code, std::string msg) {
  Error e;
  e.message = std::move(msg);
  e.field = code;
  return Unexpected{std::move(e)};
}

constexpr double kMinEdgeLength = 1e-6;  // metres: shorter lines are degenerate

}  // namespace

long FeatureModel::junction_index(const std::string& id) const {
  for (std::size_t i = 0; i < junctions_.size(); ++i)
    if (junctions_[i].id == id) return static_cast<long>(i);
  return -1;
}

Expected<void> FeatureModel::add_junction(const std::string& id, const Eigen::Vector3d& p) {
  if (id.empty()) return fail("invalid", "a feature needs an id");
  if (contains(id)) return fail("exists", fmt::format("feature '{}' exists already", id));
  if (!p.allFinite()) return fail("invalid", fmt::format("junction '{}': coordinates must be finite", id));
  junctions_.push_back({id, p});
  ids_.insert(id);
  return {};
}

Expected<void> FeatureModel::add_line(const std::string& id, const std::string& from, const std::string& to) {
  if (id.empty()) return fail("invalid", "a feature needs an id");
  if (contains(id)) return fail("exists", fmt::format("feature '{}' exists already", id));
  const long a = junction_index(from), b = junction_index(to);
  if (a < 0) return fail("not_found", fmt::format("line '{}': no junction '{}'", id, from));
  if (b < 0) return fail("not_found", fmt::format("line '{}': no junction '{}'", id, to));
  if (a == b) return fail("invalid", fmt::format("line '{}' starts and ends at junction '{}'", id, from));
  if ((junctions_[a].p - junctions_[b].p).norm() < kMinEdgeLength)
    return fail("invalid", fmt::format("line '{}': junctions '{}' and '{}' are at the same position", id, from, to));
  lines_.push_back({id, from, to});
  ids_.insert(id);
  return {};
}

Expected<void> FeatureModel::add_circle(const std::string& id, const Eigen::Vector3d& center,
                                        const Eigen::Vector3d& normal, double radius) {
  if (id.empty()) return fail("invalid", "a feature needs an id");
  if (contains(id)) return fail("exists", fmt::format("feature '{}' exists already", id));
  if (!center.allFinite() || !normal.allFinite() || !std::isfinite(radius))
    return fail("invalid", fmt::format("circle '{}': numbers must be finite", id));
  if (normal.norm() < 1e-9) return fail("invalid", fmt::format("circle '{}': the normal is zero", id));
  if (radius <= 0.0) return fail("invalid", fmt::format("circle '{}': the radius must be > 0", id));
  circles_.push_back({id, center, normal.normalized(), radius});
  ids_.insert(id);
  return {};
}

Expected<void> FeatureModel::remove(const std::string& id) {
  if (!contains(id)) return fail("not_found", fmt::format("no feature '{}'", id));
  if (const long j = junction_index(id); j >= 0) {
    for (const LineDef& l : lines_)
      if (l.from == id || l.to == id)
        return fail("in_use", fmt::format("junction '{}' is used by line '{}': remove the line first", id, l.id));
    junctions_.erase(junctions_.begin() + j);
    ids_.erase(id);
    return {};
  }
  if (auto it = std::find_if(lines_.begin(), lines_.end(), [&](const LineDef& l) { return l.id == id; });
      it != lines_.end()) {
    lines_.erase(it);
    ids_.erase(id);
    return {};
  }
  if (auto it = std::find_if(circles_.begin(), circles_.end(), [&](const CircleDef& c) { return c.id == id; });
      it != circles_.end()) {
    circles_.erase(it);
    ids_.erase(id);
    return {};
  }
  return fail("not_found", fmt::format("no feature '{}'", id));
}

Expected<std::shared_ptr<const model::Model>> FeatureModel::build(const std::string& name) const {
  model::ModelBuilder b(name);
  std::unordered_map<std::string_view, model::Index> index;
  index.reserve(junctions_.size());
  for (const JunctionDef& j : junctions_) {
    index.emplace(j.id, static_cast<model::Index>(index.size()));
    model::Attributes attr;
    attr.name = j.id;
    b.add_junction(j.p, std::move(attr));
  }
  for (const LineDef& l : lines_) {
    model::Attributes attr;
    attr.name = l.id;
    b.add_line(index.at(l.from), index.at(l.to), std::move(attr));
  }
  for (const CircleDef& c : circles_) {
    model::CircleArc arc;
    arc.center = c.center;
    arc.normal = c.normal;
    arc.x_axis = c.normal.unitOrthogonal();
    arc.radius = c.radius;
    arc.attr.name = c.id;
    b.add_arc(arc);
  }
  auto m = std::move(b).build();
  if (!m) {
    Error e = m.error();
    e.field = "invalid";
    return Unexpected{std::move(e)};
  }
  return std::shared_ptr<const model::Model>(std::make_shared<const model::Model>(std::move(*m)));
}

}  // namespace v4r::server
