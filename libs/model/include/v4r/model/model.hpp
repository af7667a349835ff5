// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "v4r/core/expected.hpp"

namespace v4r::model {

/// Index of a feature inside its Model's arrays. kNone marks "no such feature".
using Index = std::uint32_t;
inline constexpr Index kNone = std::numeric_limits<Index>::max();

/// \brief Attributes the paper attaches to model features: a name, an optional colour (RGB in
/// [0,1]) and a search level (1 = coarse, e.g. coloured regions; 2 = fine, e.g. edges).
struct Attributes {
  std::string name;
  std::optional<Eigen::Vector3f> colour;
  int search_level = 2;
};

/// \brief A 3-D point of the model (object frame, metres) and the edges that meet there.
struct Junction {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  std::vector<Index> lines;  ///< indices into Model::lines() that end at this junction
  Attributes attr;
};

/// \brief A straight edge between two junctions, with the faces it bounds (0, 1 or 2).
struct LineEdge {
  Index a = kNone, b = kNone;  ///< junction indices
  Index face_left = kNone;     ///< a face bounded by this edge, or kNone
  Index face_right = kNone;    ///< a second face bounded by this edge, or kNone
  Attributes attr;
};

/// \brief A circle arc: centre, unit normal, radius, and the angular range [start, end]
/// (radians) measured from `x_axis` (a unit vector in the circle plane) towards normal x x_axis.
/// A full circle has start = 0, end = 2*pi.
struct CircleArc {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d x_axis = Eigen::Vector3d::UnitX();
  double radius = 0.0;
  double start = 0.0;
  double end = 6.283185307179586;
  Index face = kNone;  ///< a face whose boundary contains the arc (e.g. a cylinder cap), or kNone
  Attributes attr;
};

/// \brief A planar polygonal face (region) bounded by junctions, listed counter-clockwise when
/// seen from outside, so that `normal` (unit, object frame) points out of the object.
struct Face {
  std::vector<Index> loop;  ///< junction indices, CCW from outside
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Attributes attr;
};

/// \brief A cylinder between two axis points with a radius (as in ViSP .cao). Its rims are also
/// listed as CircleArcs of the model.
struct Cylinder {
  Eigen::Vector3d p1 = Eigen::Vector3d::Zero(), p2 = Eigen::Vector3d::Zero();
  double radius = 0.0;
  Attributes attr;
};

/// \brief Immutable boundary representation of an object (paper section 2.2), coordinates in
/// the object frame (metres). Build with ModelBuilder; share as std::shared_ptr<const Model>.
class Model {
 public:
  [[nodiscard]] const std::vector<Junction>& junctions() const { return junctions_; }
  [[nodiscard]] const std::vector<LineEdge>& lines() const { return lines_; }
  [[nodiscard]] const std::vector<CircleArc>& arcs() const { return arcs_; }
  [[nodiscard]] const std::vector<Face>& faces() const { return faces_; }
  [[nodiscard]] const std::vector<Cylinder>& cylinders() const { return cylinders_; }
  [[nodiscard]] const std::string& name() const { return name_; }
  /// Radius of the smallest origin-centred sphere that holds every junction (metres).
  [[nodiscard]] double bounding_radius() const { return bounding_radius_; }
  [[nodiscard]] Eigen::Vector3d line_point_a(Index i) const { return junctions_[lines_[i].a].p; }
  [[nodiscard]] Eigen::Vector3d line_point_b(Index i) const { return junctions_[lines_[i].b].p; }

 private:
  friend class ModelBuilder;
  friend Model with_face_colour(const Model& m, const Eigen::Vector3f& rgb);
  std::string name_;
  std::vector<Junction> junctions_;
  std::vector<LineEdge> lines_;
  std::vector<CircleArc> arcs_;
  std::vector<Face> faces_;
  std::vector<Cylinder> cylinders_;
  double bounding_radius_ = 0.0;
};

/// \brief Whether ModelBuilder::add_face also adds the face's boundary edges as lines.
enum class FaceEdges { kAdd, kSkip };

/// \brief Builds a Model feature by feature: junctions, lines, faces (which add their boundary
/// edges, merged with existing lines), circles and cylinders. `build()` validates and freezes.
class ModelBuilder {
 public:
  explicit ModelBuilder(std::string name = {}) { m_.name_ = std::move(name); }

  /// Adds a junction; returns its index. Duplicate positions are kept distinct.
  Index add_junction(const Eigen::Vector3d& p, Attributes attr = {});
  /// Adds a straight edge between junctions a and b, or returns the existing one between them.
  Index add_line(Index a, Index b, Attributes attr = {});
  /// Adds a face from a loop of junctions (CCW from outside, at least 3, each within
  /// `planarity_tol` metres of the loop's least-squares plane, whose normal the face gets). With FaceEdges::kAdd its boundary edges are added with add_line and
  /// linked to the face; with FaceEdges::kSkip no line is added (link lines with set_line_faces).
  Expected<Index> add_face(const std::vector<Index>& loop, Attributes attr = {}, double planarity_tol = 1e-4,
                           FaceEdges edges = FaceEdges::kAdd);
  /// Sets the faces bounded by an existing line (kNone leaves a side empty).
  Expected<void> set_line_faces(Index line, Index face_left, Index face_right);
  /// Adds a circle arc (normal and x_axis are normalised, x_axis made orthogonal to normal).
  Index add_arc(CircleArc arc);
  /// Adds a cylinder and its two rim circles.
  Index add_cylinder(const Cylinder& c);

  [[nodiscard]] std::size_t junction_count() const { return m_.junctions_.size(); }
  [[nodiscard]] std::size_t line_count() const { return m_.lines_.size(); }
  [[nodiscard]] std::size_t face_count() const { return m_.faces_.size(); }

  /// Validates (indices in range, finite coordinates, non-degenerate edges) and returns the model.
  Expected<Model> build() &&;

 private:
  Model m_;
};

}  // namespace v4r::model
