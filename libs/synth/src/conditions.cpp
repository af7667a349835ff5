// v4r - robust model-based object tracking. MIT licence.
#include "v4r/synth/conditions.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <array>
#include <utility>

namespace v4r::synth {
namespace {

constexpr std::array<std::pair<Condition, std::string_view>, 9> kNames{{{Condition::kRegular, "regular"},
                                                                        {Condition::kLight, "light"},
                                                                        {Condition::kShadow, "shadow"},
                                                                        {Condition::kNoise, "noise"},
                                                                        {Condition::kClutter, "clutter"},
                                                                        {Condition::kOcclusion, "occlusion"},
                                                                        {Condition::kSpecular, "specular"},
                                                                        {Condition::kBlur, "blur"},
                                                                        {Condition::kFast, "fast"}}};

constexpr double kNoiseSigma = 8.0;    ///< grey levels
constexpr double kSaltPepper = 0.002;  ///< fraction of pixels
constexpr double kSpecularStrength = 1.0;
constexpr int kBlurSamples = 5;
constexpr double kFastSpeed = 3.0;  ///< speed factor of the fast condition

}  // namespace

const std::vector<Condition>& all_conditions() {
  static const std::vector<Condition> all = [] {
    std::vector<Condition> v;
    for (const auto& [c, name] : kNames) v.push_back(c);
    return v;
  }();
  return all;
}

const std::vector<std::string>& condition_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (const auto& [c, name] : kNames) v.emplace_back(name);
    return v;
  }();
  return names;
}

std::string_view condition_name(Condition c) {
  for (const auto& [k, name] : kNames)
    if (k == c) return name;
  return "?";
}

Expected<Condition> parse_condition(std::string_view name) {
  for (const auto& [c, n] : kNames)
    if (n == name) return c;
  return Unexpected{
      Error{fmt::format("unknown condition '{}' (expected one of: {})", name, fmt::join(condition_names(), ", ")),
            {},
            0,
            0,
            "condition"}};
}

RenderOptions options_for(Condition c, RenderOptions base) {
  switch (c) {
    case Condition::kRegular:
    case Condition::kFast:
      break;
    case Condition::kLight:
      base.light_change.enabled = true;
      break;
    case Condition::kShadow:
      base.shadow.enabled = true;
      break;
    case Condition::kNoise:
      base.noise_sigma = kNoiseSigma;
      base.salt_pepper = kSaltPepper;
      break;
    case Condition::kClutter:
      base.clutter.enabled = true;
      break;
    case Condition::kOcclusion:
      base.occluder.enabled = true;
      break;
    case Condition::kSpecular:
      base.specular.strength = kSpecularStrength;
      break;
    case Condition::kBlur:
      base.blur_samples = kBlurSamples;
      break;
  }
  return base;
}

TrajectorySpec trajectory_spec_for(Condition c, TrajectorySpec base) {
  if (c == Condition::kFast) base.speed *= kFastSpeed;
  return base;
}

}  // namespace v4r::synth
