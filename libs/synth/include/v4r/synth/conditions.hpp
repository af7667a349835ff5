// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "v4r/core/expected.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::synth {

/// \brief Named rendering conditions of the test sequences, from easy (regular) to hard.
/// Each one changes one aspect of the regular sequence:
///   regular    the defaults (RenderOptions{}, TrajectorySpec as given)
///   light      global brightness x0.5 .. x1.4 and a light direction turning by up to 100 degrees
///   shadow     a soft-edged (10 px penumbra) shadow band darkening by 50 % sweeps across the image
///   noise      sensor noise sigma 8 grey levels and 0.2 % salt-and-pepper pixels
///   clutter    strong static lines and ellipses in the background, some parallel to the
///              object's silhouette edges 20..40 px outside it
///   occlusion  an opaque textured forearm sweeps in front of the object, covering 38 % of it at
///              mid-sequence
///   specular   Blinn-Phong highlights of steel with saturated glints
///   blur       motion blur: 5 sub-frames per frame along the motion from the previous pose
///   fast       the trajectory's speed x3
enum class Condition { kRegular, kLight, kShadow, kNoise, kClutter, kOcclusion, kSpecular, kBlur, kFast };

/// All conditions, in the order above.
const std::vector<Condition>& all_conditions();
/// The names accepted by parse_condition, in the order above ("regular", "light", ...).
const std::vector<std::string>& condition_names();
/// The name of a condition ("shadow").
std::string_view condition_name(Condition c);
/// Parses a condition name (exact, lower case). The error lists the valid names.
Expected<Condition> parse_condition(std::string_view name);

/// `base` with condition `c` applied (the default base is the regular condition). Conditions
/// compose: options_for(kNoise, options_for(kShadow)) has both. kFast changes nothing here.
RenderOptions options_for(Condition c, RenderOptions base = {});
/// `base` with condition `c` applied to the trajectory: kFast multiplies the speed by 3; the
/// other conditions return `base` unchanged.
TrajectorySpec trajectory_spec_for(Condition c, TrajectorySpec base);

}  // namespace v4r::synth
