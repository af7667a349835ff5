// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <array>
#include <cstdint>

#include <Eigen/Core>

#include "v4r/image/colour_view.hpp"
#include "v4r/image/image_view.hpp"

namespace v4r::features {

/// \brief Settings of the silhouette-contrast test.
struct SilhouetteContrastParams {
  /// Distances of the colour samples from the edge, on both sides (pixels): clear of the edge's
  /// own blur, close enough to stay on the object.
  std::array<double, 3> offsets_px{3.0, 6.0, 10.0};
  double match_share = 0.05;    ///< an outside sample looks like the object when this share of the inside samples is in its colour bin's neighbourhood
  /// > 0: an outside sample is compared with the inside samples of its own group (add_point's
  /// `group`: one silhouette edge, whose inside is one face) when the group has at least this
  /// many, else with all of them. An object of lit and shaded faces (a grey plate in shadow
  /// beside a bright one) then does not count a dark background as its own colour along the
  /// bright face. 0: every outside sample is compared with all inside samples.
  int min_group_samples = 0;
};

/// \brief Does the image around the projected silhouette look like the object inside and like
/// something else outside? (A region cue beside the edge evidence: a pose whose silhouette edge
/// lies on a texture edge of the object itself, or on the far side of a face, leaves the object's
/// own colours outside it.)
///
/// Samples colours at fixed distances inside and outside along silhouette edges (one side the
/// object, the other not), bins the inside ones by chromaticity (g, r of g + r + b) and log
/// brightness, and counts the outside samples whose bin neighbourhood holds at least
/// `match_share` of the inside samples: the *leak*. A pose on the object's real outline leaks
/// little where the object differs from its surroundings; a nested or shifted pose leaks a share
/// that grows with how much of its outline lies on the object. On objects coloured like their
/// background the leak is high for every pose: it is meaningful only against what the same
/// object showed while tracked (pipeline). Grey images use the brightness alone. Allocates
/// nothing, never throws.
class SilhouetteContrast {
 public:
  static constexpr int kMaxSamples = 1024;  ///< per side; samples beyond are not taken
  explicit SilhouetteContrast(const SilhouetteContrastParams& p = {}) : p_(p) {}
  [[nodiscard]] const SilhouetteContrastParams& params() const { return p_; }

  /// Starts a new count.
  void reset();
  /// Colour samples at the offsets inside and outside of the silhouette point `p` (pixels);
  /// `outward` is the unit normal pointing away from the object. `colour` may be empty (then
  /// `grey` is used). Pairs with a sample outside the image are skipped. `inside_extent_px`: how
  /// far the object reaches inwards from `p` (a thin plate seen edge-on: a few pixels); inside
  /// samples are taken at most that deep (at least 1 px), outside ones at every offset.
  /// `group`: the silhouette edge the point lies on (see min_group_samples); the points of one
  /// group are added one after another.
  void add_point(const image::ImageView& grey, const image::ColourView& colour, const Eigen::Vector2d& p,
                 const Eigen::Vector2d& outward, double inside_extent_px = kUnbounded, std::uint32_t group = 0);
  static constexpr double kUnbounded = 1e9;
  /// Counts the leak over the samples added since reset().
  void finish();

  [[nodiscard]] int samples() const { return outside_n_; }  ///< outside samples taken
  [[nodiscard]] int leaked() const { return leaked_; }      ///< of these, looking like the object (after finish())

 private:
  static constexpr int kChromaBins = 34;  // 0.03 wide over [0, 1]
  static constexpr int kLogBins = 28;     // 0.25 wide over log(1 .. 766)
  static int bin_of(const float bgr[3]);
  bool sample(const image::ImageView& grey, const image::ColourView& colour, const Eigen::Vector2d& p, int* bin) const;
  using Histogram = std::array<std::uint16_t, kChromaBins * kChromaBins * kLogBins>;
  // Whether `need` or more of the histogram's samples lie in the bin's neighbourhood.
  static bool looks_inside(const Histogram& h, int bin, int need);

  SilhouetteContrastParams p_;
  Histogram hist_{};        // all inside samples
  Histogram group_hist_{};  // one group's inside samples (min_group_samples > 0)
  std::array<int, kMaxSamples> inside_{}, outside_{};
  std::array<std::uint32_t, kMaxSamples> group_{};
  int inside_n_ = 0, outside_n_ = 0, leaked_ = 0;
};

}  // namespace v4r::features
