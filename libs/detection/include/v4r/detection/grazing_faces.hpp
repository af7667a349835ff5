// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"

namespace v4r::detection {

/// \brief Poses that unfold a face seen edge-on. A narrow face beside a large one, seen at a
/// grazing angle (a box's side below its lit top), shows as a thin strip between two parallel
/// edges. An edge alignment that starts some degrees off pulls both edges of the strip onto the
/// stronger one and settles with the face turned just out of view: a pose off by a few degrees
/// whose fewer edge samples nearly all match. This class proposes the pose turned so that such a
/// face is seen again, for the caller to polish and compare.
///
/// Faces are the model's planar faces of at least `min_area_share` of the largest one's area
/// (a facet of a curved mesh is not a face worth unfolding). Allocates at construction only.
class GrazingFaces {
 public:
  GrazingFaces(const model::Model& model, double min_area_share = 0.1);

  /// For each face turned away from the camera by at most `band_rad` or seen at less than
  /// `seen_rad` (largest faces first, at most out.size()), the pose turned about the axis through
  /// `pivot_obj` (object frame) that shows that face at `seen_rad`. Returns the poses written.
  std::size_t unfold(const geometry::SE3& T_cam_obj, const Eigen::Vector3d& pivot_obj, double band_rad, double seen_rad,
                     std::span<geometry::SE3> out) const;

  [[nodiscard]] std::size_t size() const { return faces_.size(); }

 private:
  struct FaceInfo {
    Eigen::Vector3d centroid, normal;  // object frame
    double area = 0.0;
  };
  /// Elevation of the line of sight to the face's centre (the mean of its corners) above its
  /// plane: > 0 seen, < 0 turned away.
  static double seen_angle(const geometry::SE3& T_cam_obj, const FaceInfo& f);
  std::vector<FaceInfo> faces_;  // by decreasing area
};

}  // namespace v4r::detection
