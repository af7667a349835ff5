// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <vector>

#include "v4r/features/ellipse_tracker.hpp"
#include "v4r/model/model.hpp"
#include "v4r/pipeline/camera_image.hpp"
#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/pipeline/measure_context.hpp"
#include "v4r/pipeline/observation_buffer.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief The measurement unit of circle arcs (paper 3.2): tracks each visible arc's ellipse
/// along tracking lines across the projected circle and turns its edge points into circle
/// observations. Allocates only in its constructor and reserve().
class ArcMeasurement {
 public:
  explicit ArcMeasurement(const CycleParams& p);
  void reserve();
  /// Measures the view's visible arcs; returns how many are found (see LineMeasurement::track).
  int track(const model::Model& model, scene::View& view, const scene::Camera& cam, const CameraImage& img,
            MeasureContext& ctx);
  /// Appends up to circle_max_points evenly spread edge points per found ellipse.
  void observations(const model::Model& model, const scene::View& view, const scene::Camera& cam,
                    std::uint16_t view_index, std::uint8_t camera, ObservationBuffer& out) const;

 private:
  CycleParams p_;
  features::EllipseTracker tracker_, searcher_, reduced_tracker_;
  std::vector<features::CurveSample> curve_;
};

}  // namespace v4r::pipeline
