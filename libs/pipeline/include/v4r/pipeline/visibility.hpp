// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"

namespace v4r::pipeline {

/// \brief Parameters of the visibility test (issue: only edges that can be seen are tracked).
struct VisibilityParams {
  double appear_angle = 1.562;    ///< radians: a hidden face becomes visible below this view angle
  double disappear_angle = 1.569; ///< radians: a visible face becomes hidden above this view angle
  double grazing_angle = 1.65;    ///< radians: hidden faces below this view angle may still show as slivers
  double crease_angle = 0.05;     ///< radians: an edge between faces closer than this in normal is no edge
  int samples = 12;               ///< points per edge tested for occlusion and image bounds
  double image_margin = 4.0;      ///< pixels: points nearer the border count as outside
  double min_length_px = 15.0;    ///< visible parts shorter than this are not tracked
  /// metres: another object's face hides a point only when it lies in front of it by more than
  /// this along the line of sight (two tracked poses are each uncertain by about a millimetre:
  /// objects in contact, or two models of one object, do not hide each other's edges on the contact)
  double occluder_margin = 0.003;
};

/// \brief The visible part of a model edge: parameters s0 < s1 in [0, 1] along a->b.
struct EdgeVisibility {
  bool visible = false;
  /// Not visible, but bounding a face seen at a grazing angle: with a slightly different pose it
  /// may show as a sliver next to a visible edge. Not tracked; used to detect ambiguous edges.
  bool grazing = false;
  double s0 = 0.0, s1 = 1.0;
};

/// \brief Decides which model edges can be seen from a pose: faces turned away are dropped with
/// hysteresis (appear/disappear angles), and edge points hidden behind other faces of the same
/// model (depth test along the line of sight) or outside the image are cut away. Allocates its
/// buffers once per model size; update() then allocates nothing.
class VisibilityTester {
 public:
  explicit VisibilityTester(const VisibilityParams& p = {}) : p_(p) {}
  [[nodiscard]] const VisibilityParams& params() const { return p_; }
  VisibilityParams& params() { return p_; }

  /// Updates `face_visible` (one byte per face, hysteresis state) and writes one EdgeVisibility
  /// per model line into `out` (size = model.lines().size()).
  void update(const model::Model& model, const geometry::SE3& T_cam_obj, const geometry::PinholeCamera& cam,
              std::span<std::uint8_t> face_visible, std::span<EdgeVisibility> out);

  /// Other objects of the scene seen by the same camera: their faces turned towards the camera
  /// and their cylinders hide this model's edges behind them too (by depth along the line of
  /// sight), until clear_occluders(). Buffers grow only when more occluding geometry is added
  /// than ever before.
  void clear_occluders();
  void add_occluder(const model::Model& model, const geometry::SE3& T_cam_obj);

  /// After update(): whether a point of the model (camera frame) is hidden by a face other than
  /// `face_a` / `face_b`, by one of the model's cylinders (solids: side and caps) or by an occluder.
  [[nodiscard]] bool hidden(const Eigen::Vector3d& p_cam, model::Index face_a = model::kNone,
                            model::Index face_b = model::kNone) const;

 private:
  struct FaceCache {
    Eigen::Vector3d n_cam;  // plane normal, camera frame
    double d = 0.0;         // plane offset: n_cam . X = d
    Eigen::Vector2d lo, hi; // bounding box in normalised image coordinates
    std::uint32_t first = 0, count = 0;  // polygon vertices in poly_ (normalised coordinates)
    bool usable = false;
  };
  bool occluded(const Eigen::Vector3d& p_cam, model::Index face_a, model::Index face_b) const;
  /// Fills a face cache (polygon into `poly` from `cursor`) for a face of `model` at T_cam_obj.
  static void cache_face(const model::Model& model, const model::Face& f, const geometry::SE3& T_cam_obj,
                         const Eigen::Vector3d& cam_in_obj, FaceCache& c, std::vector<Eigen::Vector2d>& poly);

  VisibilityParams p_;
  struct CylinderCache {
    Eigen::Vector3d p1, axis;  // camera frame; axis unit from p1 to p2
    double length = 0.0, radius = 0.0;
  };
  /// Whether another object's geometry (add_occluder) hides the point p_cam.
  bool hidden_by_other_object(const Eigen::Vector3d& p_cam) const;
  bool hidden_by_cylinder(const Eigen::Vector3d& p_cam) const;
  static bool cylinder_hides(std::span<const CylinderCache> list, const Eigen::Vector3d& p_cam);
  /// Appends the model's cylinders at T_cam_obj (camera frame) to `out`.
  static void add_cylinders(const model::Model& model, const geometry::SE3& T_cam_obj, std::vector<CylinderCache>& out);
  std::vector<FaceCache> faces_;
  std::vector<CylinderCache> cylinders_;
  std::vector<Eigen::Vector2d> poly_;
  std::vector<std::uint8_t> sample_ok_;
  std::vector<std::uint8_t> grazing_;  // per face: hidden but seen at a grazing angle
  // Other objects' geometry (add_occluder): faces turned towards the camera, their polygons, cylinders.
  std::vector<FaceCache> occluder_faces_;
  std::vector<Eigen::Vector2d> occluder_poly_;
  std::vector<CylinderCache> occluder_cylinders_;
};

}  // namespace v4r::pipeline
