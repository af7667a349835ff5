// v4r - robust model-based object tracking. MIT licence.
// The rendered test objects of the end-to-end tests, at the distance each is tracked from.
#pragma once

#include <string>

#include "v4r/synth/renderer.hpp"

namespace v4r::test {

struct ObjectCase {
  const char* name;
  std::string (*cao)();
  double distance;  ///< metres from the camera
};

inline const ObjectCase kObjects[] = {{"box", &synth::box_cao, 0.55},
                                      {"ship", &synth::ship_mockup_cao, 0.7},
                                      {"flange", &synth::flange_cao, 0.5}};

}  // namespace v4r::test
