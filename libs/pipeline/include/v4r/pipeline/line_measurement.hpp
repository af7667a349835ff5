// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <vector>

#include "v4r/features/line_tracker.hpp"
#include "v4r/pipeline/camera_image.hpp"
#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/pipeline/measure_context.hpp"
#include "v4r/pipeline/observation_buffer.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief The measurement unit of straight edges (paper 3.1): tracks the line features of a
/// view in oriented windows at their projection (a wide search window for features not found in
/// the last frame, wider after bad frames; the narrow tracking window for found ones) and turns
/// the found ones into line observations (undistorted, normalised). Allocates only in its
/// constructor and reserve().
class LineMeasurement {
 public:
  explicit LineMeasurement(const CycleParams& p);
  /// Grows the buffers for windows of up to this many rows.
  void reserve(std::size_t rows);
  /// Measures the view's visible line features; returns how many are found. Later passes
  /// (ctx.first_pass false) measure only the features marked `retrack`.
  int track(scene::View& view, const scene::Camera& cam, const CameraImage& img, MeasureContext& ctx);
  /// Appends a line observation per found feature, tagged with `camera` (index into the
  /// buffer's cameras) and `view` (index into Object::views).
  void observations(const scene::View& view, std::uint16_t view_index, std::uint8_t camera,
                    ObservationBuffer& out) const;

 private:
  CycleParams p_;
  features::LineTracker tracker_, reduced_tracker_;
  std::vector<features::LineTracker> searchers_;  // per search level
  std::vector<Eigen::Vector2d> undistorted_;       // edge pixels of one feature, normalised
};

}  // namespace v4r::pipeline
