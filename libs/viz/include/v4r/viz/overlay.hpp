// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "v4r/pipeline/vision_cycle.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::viz {

/// \brief What draw_overlay adds besides the edges.
struct OverlayStyle {
  std::string object_label;  ///< name shown for every object (empty: the object's own name)
  bool axes = true;          ///< the object's axes at its origin (x red, y green, z blue)
  bool legend = true;        ///< the colour key in the lower right corner
};

/// \brief Draws what the vision cycle saw into a BGR image of camera `camera`: the projected
/// model edges (green: found, yellow: outlier, red: visible but not found, grey: ambiguous), the edge
/// pixels found (cyan), the object's axes, a status line per object on a dark band (found/visible
/// edges and circles; observations used by the pose solve: lines, circle points, junctions) and a
/// legend of the colours.
void draw_overlay(cv::Mat& bgr, const scene::Scene& scene, const pipeline::VisionCycle& cycle, std::size_t camera,
                  const pipeline::CycleReport& report, const OverlayStyle& style = {});

}  // namespace v4r::viz
