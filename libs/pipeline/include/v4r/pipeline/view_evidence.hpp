// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include "v4r/features/edge_evidence.hpp"
#include "v4r/pipeline/camera_image.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief The image evidence of a view at its pose (issue "an honest state"): samples along
/// every visible edge and circle of the projected model, tracked or not, test for a gradient of
/// matching position and orientation (features::EdgeEvidence). Writes View::evidence_samples
/// and View::evidence_matched. Allocates nothing.
void measure_view_evidence(features::EdgeEvidence& evidence, scene::View& view, const scene::Camera& cam,
                           const CameraImage& img);

}  // namespace v4r::pipeline
