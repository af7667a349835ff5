// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <Eigen/Core>

#include "v4r/image/image_view.hpp"

namespace v4r::features {

/// \brief Settings of the edge-evidence test.
struct EdgeEvidenceParams {
  double step_px = 6.0;          ///< spacing of the samples along a projected edge, pixels
  int max_samples_per_edge = 40;  ///< longer edges are sampled more sparsely
  int search_px = 2;             ///< a sample looks for its edge this far on either side, pixels (at most 8)
  double max_angle_rad = 0.35;   ///< largest angle between the image gradient and the predicted edge normal
  float min_gradient = 3.0f;     ///< floor of the gradient threshold, grey levels per pixel
};

/// \brief Does the image show the model where the pose puts it? Counts, over samples along the
/// whole projected model, how many find an image gradient of matching position (within
/// `search_px` across the edge) and orientation (within `max_angle_rad` of the predicted normal,
/// either sign) above a threshold. The share of matched samples is the image's evidence for a
/// pose, independent of which features the tracker used (it also samples edges the tracker left
/// out). The gradient across is that of the profile averaged over 5 pixels along the edge (grey
/// levels per pixel), robust to sensor noise. Allocates nothing, never throws.
class EdgeEvidence {
 public:
  static constexpr int kMaxSearch = 8;
  explicit EdgeEvidence(const EdgeEvidenceParams& p = {}) : p_(p) {}
  [[nodiscard]] const EdgeEvidenceParams& params() const { return p_; }
  void set_params(const EdgeEvidenceParams& p) { p_ = p; }

  /// Starts a new count.
  void reset() { samples_ = matched_ = 0; }
  /// One sample at pixel `p` with unit edge normal `n`; `threshold` (grey levels per pixel) is
  /// raised to min_gradient. Samples whose search reaches outside the image are not counted.
  /// Returns whether it matched.
  bool add_sample(const image::ImageView& img, const Eigen::Vector2d& p, const Eigen::Vector2d& n, float threshold);
  /// Samples a straight image segment a-b (spacing step_px, at most max_samples_per_edge, at
  /// least one); returns the number of matched samples.
  int add_segment(const image::ImageView& img, const Eigen::Vector2d& a, const Eigen::Vector2d& b, float threshold);
  /// Number of samples along a segment of this length.
  [[nodiscard]] int samples_for_length(double length_px) const;

  [[nodiscard]] int samples() const { return samples_; }
  [[nodiscard]] int matched() const { return matched_; }
  /// matched / samples (0 without samples).
  [[nodiscard]] double share() const { return samples_ > 0 ? static_cast<double>(matched_) / samples_ : 0.0; }

 private:
  EdgeEvidenceParams p_;
  int samples_ = 0, matched_ = 0;
};

}  // namespace v4r::features
