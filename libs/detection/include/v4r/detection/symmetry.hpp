// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <vector>

#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"

namespace v4r::detection {

/// \brief The proper symmetries of a model among the 24 rotations that map the axes of its
/// object frame onto each other, about the centre of its bounding box: the transforms S (object
/// frame to object frame) with S(model) == model (every junction onto a junction, every line
/// onto a line, every cylinder onto a cylinder, within `tol` metres). Always holds the identity.
/// An edge-based detector cannot tell T_cam_obj from T_cam_obj * S.
std::vector<geometry::SE3> model_symmetries(const model::Model& model, double tol = 1e-6);

/// \brief The near symmetries of a model: the rotations of model_symmetries that map it onto
/// itself within `relative_tol` of its bounding box's diagonal but are not exact symmetries (a
/// ship section whose two walls differ in height by 2 cm, turned about its vertical axis). An
/// edge-based detector can barely tell T_cam_obj from T_cam_obj * S; empty for relative_tol <= 0.
std::vector<geometry::SE3> near_symmetries(const model::Model& model, double relative_tol);

/// \brief Translation (metres) and rotation (radians) error of `estimate` against `truth`, the
/// smallest over the symmetries (T_cam_obj * S, S from model_symmetries).
struct PoseError {
  double translation = 0.0;
  double rotation = 0.0;
};
PoseError symmetric_pose_error(const geometry::SE3& estimate, const geometry::SE3& truth,
                               const std::vector<geometry::SE3>& symmetries);

/// \brief Of the poses `T * S` (S from model_symmetries, identity included) the one nearest to
/// `reference` (rotation angle first, then translation, as symmetric_pose_error orders them): the
/// image cannot tell them apart, continuity can (an object found again after a loss is reported in
/// the equivalent pose nearest to where it was last seen).
geometry::SE3 nearest_symmetric(const geometry::SE3& T, const geometry::SE3& reference,
                                const std::vector<geometry::SE3>& symmetries);

}  // namespace v4r::detection
