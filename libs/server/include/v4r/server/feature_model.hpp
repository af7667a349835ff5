// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <unordered_set>
#include <vector>

#include <Eigen/Core>

#include "v4r/core/expected.hpp"
#include "v4r/model/model.hpp"

namespace v4r::server {

/// \brief The features of an object built feature by feature (`AddFeature` / `RemoveFeature`):
/// junctions, lines between junctions and circles, keyed by the client's ids (one id space per
/// object), in the order they were added. build() turns them into an immutable Model. The lines
/// bound no face, so the tracker treats every one of them as a visible candidate.
/// Errors set `Error::field` to a protocol error code: `exists`, `not_found`, `in_use`, `invalid`.
class FeatureModel {
 public:
  /// Adds a junction at `p` (object frame, metres).
  Expected<void> add_junction(const std::string& id, const Eigen::Vector3d& p);
  /// Adds a straight edge between two existing junctions (distinct, not at the same position).
  Expected<void> add_line(const std::string& id, const std::string& from, const std::string& to);
  /// Adds a full circle: centre (metres), normal of its plane (any length > 0), radius (metres, > 0).
  Expected<void> add_circle(const std::string& id, const Eigen::Vector3d& center, const Eigen::Vector3d& normal,
                            double radius);
  /// Removes a feature. A junction still used by a line cannot be removed (remove the lines first).
  Expected<void> remove(const std::string& id);

  [[nodiscard]] bool contains(const std::string& id) const { return ids_.count(id) > 0; }
  [[nodiscard]] std::size_t junction_count() const { return junctions_.size(); }
  [[nodiscard]] std::size_t line_count() const { return lines_.size(); }
  [[nodiscard]] std::size_t circle_count() const { return circles_.size(); }
  /// True when there is something to track (a line or a circle).
  [[nodiscard]] bool trackable() const { return !lines_.empty() || !circles_.empty(); }

  /// Builds the Model (named `name`) in time linear in the number of features; features keep
  /// their ids as attribute names.
  [[nodiscard]] Expected<std::shared_ptr<const model::Model>> build(const std::string& name) const;

 private:
  struct JunctionDef {
    std::string id;
    Eigen::Vector3d p;
  };
  struct LineDef {
    std::string id, from, to;
  };
  struct CircleDef {
    std::string id;
    Eigen::Vector3d center, normal;
    double radius;
  };
  [[nodiscard]] long junction_index(const std::string& id) const;

  std::unordered_set<std::string> ids_;  // every feature id, for O(1) duplicate checks
  std::vector<JunctionDef> junctions_;
  std::vector<LineDef> lines_;
  std::vector<CircleDef> circles_;
};

}  // namespace v4r::server
