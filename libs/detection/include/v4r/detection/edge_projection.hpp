// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"

namespace v4r::detection {

/// \brief A point on a visible edge of the projected model: its object-frame position, its pixel
/// and the unit normal of the projected edge there (image frame, sign arbitrary).
struct EdgeSample {
  Eigen::Vector3d p_obj = Eigen::Vector3d::Zero();
  Eigen::Vector2d px = Eigen::Vector2d::Zero();
  Eigen::Vector2d normal = Eigen::Vector2d::UnitX();
  std::uint32_t piece = 0;  ///< samples of one edge piece are consecutive and share this number
  /// Set by EdgeProjector::mark_sides (0 until then). On a silhouette with background beyond it:
  /// +1 when the object lies along +normal, -1 along -normal; 0 on a crease, a circle arc, an
  /// outline against another part of the model, or where the side is not known.
  std::int8_t object_side = 0;
  /// With object_side: how far the object reaches inwards from here, in pixels (twice the distance
  /// along the normal to the front face's projected centroid, or to a limb's axis); 0 elsewhere.
  float inside_extent_px = 0.0F;
};

/// \brief Samples the edges a camera sees of a model at a pose: silhouette and crease lines
/// (a line bounded by faces shows when one of them faces the camera, and not between faces whose
/// normals differ by less than the crease angle), circle arcs and the limb lines of cylinders,
/// with hidden-line removal (a point is dropped when a face turned towards the camera, or a
/// cylinder, lies on its line of sight before it). Points outside the image are dropped.
/// Buffers are sized for the model at construction; sample() allocates nothing.
class EdgeProjector {
 public:
  /// `crease_angle` in radians.
  EdgeProjector(const model::Model& model, double crease_angle);

  /// Writes samples about `spacing_px` apart (pixels of `cam`) into `out` and returns how many;
  /// when `out` is too small, the spacing grows so that every edge is still covered evenly.
  /// `margin_px`: samples nearer the image border are dropped (< 0: no image bounds at all, for
  /// templates whose camera has no size).
  std::size_t sample(const geometry::SE3& T_cam_obj, const geometry::PinholeCamera& cam, double spacing_px,
                     std::span<EdgeSample> out, double margin_px = 2.0);

  /// After sample(), for its samples (same pose and camera): the object's side of each silhouette
  /// sample (EdgeSample::object_side, inside_extent_px). An outline whose outside, up to
  /// `probe_px` out, falls on the model itself (a wall standing on a plate, a part behind another)
  /// gets no side: beyond it is not the background.
  void mark_sides(std::span<EdgeSample> samples, double probe_px) const;

  [[nodiscard]] const model::Model& model() const { return model_; }

 private:
  struct FaceCache {
    Eigen::Vector3d n_cam = Eigen::Vector3d::UnitZ();
    double d = 0.0;
    Eigen::Vector2d lo, hi;
    std::uint32_t first = 0, count = 0;
    bool front = false;
  };
  struct CylCache {
    Eigen::Vector3d p1, axis;
    double length = 0.0, radius = 0.0;
  };
  /// One 3-D curve piece to sample: a line (a..b) or an arc.
  struct Piece {
    Eigen::Vector3d a = Eigen::Vector3d::Zero(), b = Eigen::Vector3d::Zero();  // line ends (object frame)
    int arc = -1;          // arc index or -1
    model::Index face_a = model::kNone, face_b = model::kNone;
    int cylinder = -1;     // cylinder the piece lies on (limbs: not occluded by it)
    bool silhouette = false;  // the object on one side only: a line with one front face, a limb
    // A point on the object's side at each end (object frame): a line's front face's centroid,
    // a limb's axis ends; in between, linearly.
    Eigen::Vector3d inside_a = Eigen::Vector3d::Zero(), inside_b = Eigen::Vector3d::Zero();
  };
  void prepare(const geometry::SE3& T, const geometry::PinholeCamera& cam);
  /// The front faces that may hide part of a piece whose points project (normalised image
  /// coordinates) into [lo, hi]: their boxes overlap it, and they are not the piece's own faces.
  void collect_occluders(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, model::Index fa, model::Index fb);
  /// A point is hidden by one of the collected faces or by a cylinder other than its own.
  [[nodiscard]] bool hidden(const Eigen::Vector3d& p_cam, int own_cylinder) const;
  [[nodiscard]] Eigen::Vector3d piece_point(const Piece& pc, double s) const;
  /// The ray through `q` (normalised image coordinates) meets a front face or a cylinder.
  [[nodiscard]] bool on_model(const Eigen::Vector2d& q) const;

  const model::Model& model_;
  double cos_crease_;
  geometry::SE3 T_last_;                // pose and camera of the last sample()
  geometry::PinholeCamera cam_last_;
  std::vector<FaceCache> faces_;
  std::vector<Eigen::Vector3d> centroids_;  // of the faces' loops (object frame)
  std::vector<CylCache> cyls_;
  std::vector<Eigen::Vector2d> poly_;
  std::vector<Piece> pieces_;
  std::vector<double> piece_len_;
  std::vector<Eigen::Vector2d> piece_lo_, piece_hi_;  // normalised image box of each piece
  std::vector<std::uint32_t> occluders_;               // faces collected for the current piece
};

}  // namespace v4r::detection
