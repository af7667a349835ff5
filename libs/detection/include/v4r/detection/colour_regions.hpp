// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "v4r/detection/detector_params.hpp"
#include "v4r/detection/template_set.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/image/colour_view.hpp"
#include "v4r/model/model.hpp"

namespace v4r::detection {

/// \brief A connected region of model-coloured pixels at 1/4 resolution (coarse-level pixels:
/// coarse pixel X covers full-resolution pixels 4X .. 4X+3).
struct ColourRegion {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  ///< bounding box, inclusive
  int area = 0;                        ///< pixels
};

/// \brief Where a coarse template's model-coloured faces project, relative to its anchor
/// (coarse-level pixels), and their area; area 0: no coloured face is visible in this view.
struct ColouredFootprint {
  float area = 0.0f;  ///< coarse pixels^2
  std::int16_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

/// \brief The paper's colour-region search (the sponge): at 1/4 resolution, pixels whose
/// chromaticity (normalised r = R/(R+G+B), g = G/(R+G+B)) lies within
/// detect.colour.max_distance of the model colour's are marked, grouped into 8-connected
/// regions, and regions of a plausible area for the view range (between min_area_ratio times the
/// smallest and max_area_ratio times the largest coloured area of the coarse templates) are kept,
/// the largest first. The detector then scores a coarse template only where its coloured
/// footprint covers a region of a matching area (anchor_window()).
///
/// Footprints are computed at set-up from the model's faces whose colour attribute has the same
/// chromaticity as the searched colour, with back-face culling only (exact for convex objects; a
/// coloured face hidden by another part of the model still counts). find() allocates nothing.
class ColourRegions {
 public:
  /// `rgb`: the searched colour (RGB in [0, 1]); faces of `model` whose colour has its
  /// chromaticity give the footprints. `cam` gives the image size and focal lengths.
  ColourRegions(const model::Model& model, const TemplateSet& templates, const geometry::PinholeCamera& cam,
                const Eigen::Vector3f& rgb, const ColourParams& p);

  /// Marks, groups and keeps the regions of a colour image of the camera's size; returns how
  /// many were kept (at most detect.colour.max_regions), -1 when the size differs.
  int find(const image::ColourView& bgr);

  [[nodiscard]] std::span<const ColourRegion> regions() const { return {regions_.data(), regions_.size()}; }
  [[nodiscard]] const ColouredFootprint& footprint(std::size_t coarse_template) const { return footprints_[coarse_template]; }
  /// True when some coarse template shows a coloured face (else the stage cannot help).
  [[nodiscard]] bool usable() const { return max_area_ > 0.0f; }
  /// Plausible region areas (coarse pixels) over the view range.
  [[nodiscard]] float min_region_area() const { return min_region_; }
  [[nodiscard]] float max_region_area() const { return max_region_; }
  /// The marked pixels of the last find() (255 = model colour), width() x height() (diagnosis).
  [[nodiscard]] const std::vector<std::uint8_t>& mask() const { return mask_; }
  [[nodiscard]] int width() const { return w_; }
  [[nodiscard]] int height() const { return h_; }

  /// The anchors (coarse pixels, inclusive) at which coarse template `k`'s coloured footprint
  /// holds region `r` (grown by detect.colour.margin; centred on it when the region is the
  /// larger); false when their areas do not match (region area / footprint area outside
  /// [min_area_ratio, max_area_ratio]).
  bool anchor_window(std::size_t k, const ColourRegion& r, int& ax0, int& ay0, int& ax1, int& ay1) const;

 private:
  ColourParams p_;
  int full_w_, full_h_, w_, h_;
  float r0_ = 0.0f, g0_ = 0.0f;  // chromaticity of the searched colour
  std::vector<ColouredFootprint> footprints_;
  float max_area_ = 0.0f, min_region_ = 0.0f, max_region_ = 0.0f;
  std::vector<std::uint8_t> mask_;
  std::vector<std::int32_t> stack_;
  std::vector<ColourRegion> regions_;  // capacity max_regions
};

}  // namespace v4r::detection
