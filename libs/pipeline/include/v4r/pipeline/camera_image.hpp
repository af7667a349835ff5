// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include "v4r/image/colour_view.hpp"
#include "v4r/image/image_view.hpp"

namespace v4r::pipeline {

/// \brief Images of one camera for one cycle: 8-bit grey, and optionally the BGR colour image
/// (used by cue integration).
struct CameraImage {
  image::ImageView grey;
  image::ColourView colour;  ///< empty if not available
};

}  // namespace v4r::pipeline
