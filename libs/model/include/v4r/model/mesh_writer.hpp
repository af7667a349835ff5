// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/mesh_reader.hpp"
#include "v4r/model/model.hpp"

namespace v4r::model {

/// \brief File format of a written mesh; kAuto picks it from the extension (.obj, .stl, .ply).
enum class MeshFormat { kAuto, kObj, kStlBinary, kPlyAscii };

/// \brief How a Model's surface is turned into triangles and written.
struct MeshWriteOptions {
  MeshFormat format = MeshFormat::kAuto;
  int cylinder_segments = 48;  ///< facets around each cylinder (vertices on the radius)
  bool cylinder_caps = true;   ///< close cylinders with a disc at each end
  double scale = 1.0;          ///< metres -> file units (e.g. 1000 for millimetres)
  geometry::SE3 T_file_obj{};  ///< applied before scaling: p_file = scale * (T_file_obj * p_obj)
};

/// Triangulates a Model's surface in the object frame (metres): every planar face by ear
/// clipping in its plane (a fan for convex faces), every cylinder as `cylinder_segments` side
/// quads (two triangles each) plus, optionally, a centre-fan disc at each end. Triangles are
/// counter-clockwise seen from outside. The face junctions are shared vertices.
TriangleMesh triangulate(const Model& model, int cylinder_segments = 48, bool cylinder_caps = true);

/// Writes a triangle mesh as OBJ (text, shared vertices), binary STL (triangle soup, facet
/// normals) or ASCII PLY (shared vertices, doubles). Coordinates are written as given.
Expected<void> write_mesh(const TriangleMesh& mesh, const std::string& path, MeshFormat format = MeshFormat::kAuto);

/// triangulate() then write_mesh(), with the transform and scale of `opt`.
Expected<void> write_mesh(const Model& model, const std::string& path, const MeshWriteOptions& opt = {});

}  // namespace v4r::model
