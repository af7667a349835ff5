// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include "v4r/model/model.hpp"
#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/pipeline/observation_buffer.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief The measurement unit of junctions (paper 3.3): where tracked edges meet at a model
/// junction at a clear angle, their intersection is a point observation of the junction; where a
/// straight edge runs into a circle arc along its tangent, the ellipse's point of that tangent is.
/// Reads the line and arc features the other units measured; allocates nothing.
class JunctionMeasurement {
 public:
  explicit JunctionMeasurement(const CycleParams& p) : p_(p) {}
  /// Appends the junction observations of a view (after its lines and arcs were measured).
  void observations(const model::Model& model, const scene::View& view, const scene::Camera& cam,
                    std::uint8_t camera, ObservationBuffer& out) const;

 private:
  void tangent_junctions(const model::Model& model, const scene::View& view, const scene::Camera& cam,
                         std::uint8_t camera, ObservationBuffer& out) const;
  CycleParams p_;
};

}  // namespace v4r::pipeline
