// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <Eigen/Core>

#include "v4r/model/model.hpp"

namespace v4r::model {

/// The mean of a face's loop junctions (object frame; the origin for an empty loop): a point on
/// the face's side of each of its edges for a convex face, used to tell which side of a projected
/// edge the face lies on, and where a face is seen from.
inline Eigen::Vector3d face_centroid(const Model& m, Index face) {
  const Face& f = m.faces()[face];
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const Index j : f.loop) c += m.junctions()[j].p;
  return f.loop.empty() ? c : Eigen::Vector3d(c / static_cast<double>(f.loop.size()));
}

}  // namespace v4r::model
