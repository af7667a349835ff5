// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include "v4r/features/edge_evidence.hpp"
#include "v4r/features/silhouette_contrast.hpp"
#include "v4r/pipeline/camera_image.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief The image evidence of a view at its pose (issue "an honest state"): samples along
/// every visible edge and circle of the projected model, tracked or not, test for a gradient of
/// matching position and orientation (features::EdgeEvidence). Writes View::evidence_samples
/// and View::evidence_matched.
///
/// With `contrast`, also the silhouette contrast (features::SilhouetteContrast): at the samples
/// of edges with the object on one side only (not ambiguous, not a merged pair's mid-line;
/// circles are left out) that the image confirms, colours inside and outside: is the edge the
/// object's outline or an edge on the object? Writes View::leak_samples and View::leak_matched
/// (0 without). Allocates nothing.
/// The lowest gradient threshold (grey levels per pixel) a visible, tracked edge of the view
/// needed against noise and texture (LineMeasurement::threshold); 0 when none was tracked.
float view_threshold(const scene::View& view);

void measure_view_evidence(features::EdgeEvidence& evidence, features::SilhouetteContrast* contrast, scene::View& view,
                           const scene::Camera& cam, const CameraImage& img);

}  // namespace v4r::pipeline
