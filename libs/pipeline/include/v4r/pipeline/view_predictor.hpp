// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <vector>

#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/pipeline/visibility.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief Prediction of one view (paper 2.3): from the object's predicted pose, which model
/// edges and circles the camera can see (visibility, with other objects as occluders), their
/// projection, which edges are too close side by side to be told apart (split or merged), and
/// which side of each edge shows the object (cue integration). Allocates only when a model
/// larger than any before is predicted.
class ViewPredictor {
 public:
  explicit ViewPredictor(const CycleParams& p) : p_(p), visibility_(p.visibility) {}
  /// Other objects in front of the next predicted views (see VisibilityTester::add_occluder).
  void clear_occluders() { visibility_.clear_occluders(); }
  void add_occluder(const model::Model& model, const geometry::SE3& T_cam_obj) {
    visibility_.add_occluder(model, T_cam_obj);
  }
  /// Predicts `view` of `obj` (camera `cam`) at obj.T_pred.
  void predict(const scene::Object& obj, scene::View& view, const scene::Camera& cam);

 private:
  void mark_ambiguous(scene::View& view, const scene::Camera& cam) const;
  // Leaves the shorter of two non-parallel edges out when it leaves their shared junction within
  // converging_px of the other over its whole length (CycleParams::converging_px).
  void leave_out_converging(scene::LineFeature& f, scene::LineFeature& g, double flen, double glen) const;
  CycleParams p_;
  VisibilityTester visibility_;
  std::vector<EdgeVisibility> edge_vis_;
  std::vector<model::Index> side_face_;  // per line feature, 2: the visible face on each side (kNone: none)
};

}  // namespace v4r::pipeline
