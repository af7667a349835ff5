// v4r - robust model-based object tracking. MIT licence.
#include <array>
#include <cmath>

#include "v4r/synth/renderer.hpp"

namespace v4r::synth {
namespace {

/// One sinusoidal channel: offset(k) = amp * (sin(omega k + phase) - sin(phase)), so that the
/// offset is 0 at frame 0 and spans 2 * amp peak to peak.
struct Channel {
  double omega;  ///< radians per frame at speed 1
  double phase;  ///< radians
};

// Periods between 130 and 280 frames, pairwise incommensurate: the motion does not repeat
// within 120 frames. At speed 1 the RMS inter-frame motion is about 3 mm and 0.5 degrees
// for the default amplitudes.
constexpr std::array<Channel, 3> kTranslation{{{0.047, 0.3}, {0.039, -0.5}, {0.028, 0.2}}};  // x, y, z (depth)
constexpr std::array<Channel, 3> kRotation{{{0.031, 0.4}, {0.037, -0.2}, {0.023, 0.6}}};     // about x, y, z

double offset(const Channel& c, double k, double amp) {
  return amp * (std::sin(c.omega * k + c.phase) - std::sin(c.phase));
}

}  // namespace

std::vector<geometry::SE3> make_trajectory(const TrajectorySpec& spec) {
  std::vector<geometry::SE3> out;
  if (spec.frames <= 0) return out;
  out.reserve(static_cast<std::size_t>(spec.frames));
  out.push_back(spec.T0);
  const Eigen::Matrix3d R0 = spec.T0.rotation();
  const Eigen::Vector3d t0 = spec.T0.translation();
  for (int i = 1; i < spec.frames; ++i) {
    const double k = spec.speed * i;
    const Eigen::Vector3d dt(offset(kTranslation[0], k, spec.translation_amp),
                             offset(kTranslation[1], k, spec.translation_amp),
                             offset(kTranslation[2], k, spec.depth_amp));
    const Eigen::Vector3d w(offset(kRotation[0], k, spec.rotation_amp), offset(kRotation[1], k, spec.rotation_amp),
                            offset(kRotation[2], k, spec.rotation_amp));
    // Rotation about camera-parallel axes through the object origin: the origin stays at t0 + dt.
    const Eigen::Matrix3d R = geometry::so3_exp(w) * R0;
    out.emplace_back(R, Eigen::Vector3d(t0 + dt));
  }
  return out;
}

}  // namespace v4r::synth
