// v4r - robust model-based object tracking. MIT licence.
// Internal to the synth module: the per-frame state of the rendering conditions (lighting,
// shadow band, occluder) and the drawing of background clutter.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>

#include "procedural.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::synth::detail {

inline constexpr int kDefaultCycleFrames = 120;  ///< cycle of direct render() calls (RenderOptions::cycle_frames = 0)

/// Frames per cycle of the time-varying conditions.
inline int cycle_frames(const RenderOptions& opt) {
  return opt.cycle_frames > 0 ? opt.cycle_frames : kDefaultCycleFrames;
}
/// Phase t / P in [0, 1) of frame t in its cycle.
double cycle_phase(const RenderOptions& opt, int frame);

/// \brief Lights of one frame (camera frame, unit vectors towards the lights) and the global gain.
struct FrameLighting {
  Eigen::Vector3d light = -Eigen::Vector3d::UnitZ();  ///< diffuse light
  float gain = 1.0f;                                  ///< global brightness factor
  bool specular = false;
  Eigen::Vector3d spec_light = -Eigen::Vector3d::UnitY();  ///< highlight lamp
  float spec_strength = 0, shininess = 1, sheen = 0;
};
FrameLighting lighting_at(const RenderOptions& opt, int frame);

/// \brief The shadow band of one frame: factor(x, y) multiplies the light at pixel (x, y).
struct ShadowState {
  bool on = false;
  double dx = 1, dy = 0;  ///< unit sweep direction
  double centre = 0;      ///< band centre along (dx, dy), pixels
  double half = 0, pen = 1;
  float dark = 0;
  [[nodiscard]] float factor(int x, int y) const {
    const double outside = std::abs(dx * x + dy * y - centre) - half;  // > 0 outside the band
    const float cover =
        smoothstep(static_cast<float>(0.5 * pen), static_cast<float>(-0.5 * pen), static_cast<float>(outside));
    return 1.0f - dark * cover;
  }
};
ShadowState shadow_at(const RenderOptions& opt, int frame, int width, int height);

/// \brief The occluder of one frame: a capsule (a forearm from beyond the image border to a
/// rounded tip), its coverage at a pixel (analytic anti-aliasing, 1 px ramp) and its colour.
struct OccluderState {
  bool on = false;
  OccluderLayout layout;
  double u = 0;  ///< across coordinate of the centre line in this frame
  /// Columns [xa, xb] of row y that may be covered (false: none).
  [[nodiscard]] bool row_span(int y, int width, int& xa, int& xb) const {
    const double ax = layout.across.x(), ay = layout.across.y(), reach = layout.radius_px + 1.0;
    if (!(ax > 1e-6)) {
      xa = 0;
      xb = width - 1;
      return true;
    }
    const double lo = (u - reach - ay * y) / ax, hi = (u + reach - ay * y) / ax;
    xa = std::max(0, static_cast<int>(std::floor(lo)));
    xb = std::min(width - 1, static_cast<int>(std::ceil(hi)));
    return xa <= xb;
  }
  /// Distance (pixels) from the pixel centre to the arm's centre line segment, and the
  /// coordinates (along the axis, across relative to the centre line) of the pixel.
  [[nodiscard]] double distance(int x, int y, double& along, double& across) const {
    along = layout.axis.x() * x + layout.axis.y() * y;
    across = layout.across.x() * x + layout.across.y() * y - u;
    if (along <= layout.tip) return std::abs(across);
    return std::hypot(across, along - layout.tip);
  }
  /// Fraction of the pixel covered (0..1).
  [[nodiscard]] float coverage(double dist) const {
    return static_cast<float>(std::clamp(layout.radius_px - dist + 0.5, 0.0, 1.0));
  }
  /// Colour (BGR, grey levels, before the global gain): a rounded sleeve with a fabric texture.
  [[nodiscard]] Eigen::Vector3f colour(const float* texture, double along, double across) const;
};
OccluderState occluder_at(const RenderOptions& opt, const OccluderLayout& layout, int frame);

/// The occluder's path when nothing is known about the object: over the image centre.
OccluderLayout default_occluder_layout(const Occluder& o, int width, int height);
/// The occluder's path for an object whose masks (CV_8UC1, non-zero on the object) at the start
/// and at the middle of the cycle are given: clear of the object at the start (8 px margin),
/// centred on it at mid-cycle, with the width that covers `o.peak_coverage` of its area there.
OccluderLayout layout_occluder(const Occluder& o, const cv::Mat& mask_start, const cv::Mat& mask_peak);

/// Draws the random lines and ellipses of `c` into `bg` (CV_32FC3), anti-aliased.
void draw_random_clutter(cv::Mat& bg, const Clutter& c, std::uint32_t seed);
/// Draws lines parallel to the long straight parts of the silhouette of `mask` (CV_8UC1,
/// non-zero on the object), c.near_min_px .. c.near_max_px outside it, into `bg`.
void draw_near_clutter(cv::Mat& bg, const cv::Mat& mask, const Clutter& c, std::uint32_t seed);

}  // namespace v4r::synth::detail
