// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"

namespace v4r::model {

/// \brief An indexed triangle mesh; each triangle lists its vertices counter-clockwise seen from
/// outside. Units and frame are those of whoever filled it (object frame, metres, for the reader).
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<Index, 3>> triangles;
};

/// \brief How a triangle mesh becomes a Model: units, placement, and the thresholds of the
/// trackable-feature extraction (sharp edges, collinear merge, circles, coplanar faces).
struct MeshImportOptions {
  double scale = 1.0;             ///< file units -> metres (e.g. 0.001 for millimetres)
  geometry::SE3 T_obj_file{};     ///< object-frame transform applied after scaling (metres)
  double sharp_angle = 0.35;      ///< radians: edges whose dihedral angle is above this are trackable edges
  double weld_tolerance = 1e-6;   ///< metres (after scale): vertices closer than this are merged
  double collinear_angle = 0.02;  ///< radians: consecutive sharp edge pieces within this are merged into one line
  bool detect_circles = true;     ///< recover circles from tessellated arcs
  int min_circle_segments = 8;    ///< a chain needs at least this many pieces to become a circle (arc)
  double circle_tolerance = 0.02; ///< relative radius (and plane) deviation allowed, of the radius
  bool merge_coplanar = true;     ///< edge-connected coplanar triangles become one polygon face
  double coplanar_angle = 1e-3;   ///< radians: normal deviation allowed inside a merged face
  bool fix_orientation = true;    ///< make triangle winding consistent; closed parts outward (volume > 0)
};

/// \brief What the import found and how long it took (for reports and benchmarks).
struct MeshImportStats {
  std::size_t file_vertices = 0;   ///< vertices after assimp (all meshes, all node instances)
  std::size_t file_triangles = 0;  ///< triangles after assimp's triangulation
  std::size_t welded_vertices = 0; ///< vertices after the tolerance weld
  std::size_t triangles = 0;       ///< non-degenerate triangles kept
  std::size_t flipped_triangles = 0;
  std::size_t sharp_pieces = 0;    ///< mesh edges classified as sharp (incl. open boundary edges)
  std::size_t boundary_pieces = 0; ///< of which open-boundary edges (one triangle)
  std::size_t faces = 0, lines = 0, circles = 0, junctions = 0;
  double read_ms = 0.0;     ///< assimp import and transform
  double extract_ms = 0.0;  ///< weld, feature extraction and model build
};

/// \brief Loads a mesh file (OBJ, PLY, STL and whatever else assimp reads; all meshes of the
/// scene, placed by their node transforms) and extracts trackable features:
/// - faces: coplanar edge-connected triangles merged into planar polygons (outward normals), or
///   the triangles themselves where a merged region is not a simple polygon (e.g. has a hole);
/// - lines: sharp edges (dihedral angle > sharp_angle) and open-boundary edges, collinear pieces
///   merged into one LineEdge between junctions, linked to their two dominant faces (face_left is
///   the face whose loop runs from line.a to line.b);
/// - circles: chains of sharp pieces whose vertices lie on a circle become CircleArcs (full
///   circles, or arcs with start = 0 and end = swept angle counter-clockwise about the normal);
///   the normal points away from the surface that meets the circle (a cap's outward normal).
/// Points are p_obj = T_obj_file * (scale * p_file). Errors name the file.
Expected<Model> load_mesh(const std::string& path, const MeshImportOptions& opt = {}, MeshImportStats* stats = nullptr);

/// Reads all triangles of a mesh file into one mesh, scaled and transformed (object frame,
/// metres) but neither welded nor cleaned.
Expected<TriangleMesh> read_triangle_mesh(const std::string& path, const MeshImportOptions& opt = {},
                                          MeshImportStats* stats = nullptr);

/// Feature extraction of load_mesh on a mesh already in the object frame (metres): `scale` and
/// `T_obj_file` of `opt` are ignored. `source` names the input in errors and is the model name.
Expected<Model> mesh_to_model(const TriangleMesh& mesh, const std::string& source, const MeshImportOptions& opt = {},
                              MeshImportStats* stats = nullptr);

}  // namespace v4r::model
