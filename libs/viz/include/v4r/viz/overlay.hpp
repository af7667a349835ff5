// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <opencv2/core.hpp>

#include "v4r/pipeline/vision_cycle.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::viz {

/// \brief Draws what the vision cycle saw into a BGR image of camera `camera`: the projected
/// model edges (green: found, yellow: outlier, red: visible but not found, grey: ambiguous), the edge
/// pixels found (cyan) and a status line per object.
void draw_overlay(cv::Mat& bgr, const scene::Scene& scene, const pipeline::VisionCycle& cycle, std::size_t camera,
                  const pipeline::CycleReport& report);

}  // namespace v4r::viz
