// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "v4r/detection/detector_params.hpp"
#include "v4r/detection/edge_projection.hpp"
#include "v4r/detection/gradient_pyramid.hpp"
#include "v4r/features/silhouette_contrast.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/image/colour_view.hpp"
#include "v4r/model/model.hpp"

namespace v4r::detection {

/// \brief The verdict of the edge test on one pose.
struct Verification {
  /// Share of the projected model's edge samples with a matching gradient that lie in runs of
  /// matches along their edge (0..1): scattered matches, as texture gives them, do not count.
  double score = 0.0;
  int samples = 0;     ///< visible edge samples of the model at the pose
  int matched = 0;     ///< ... of which matched a gradient in position and orientation
  int in_runs = 0;     ///< matched samples in runs of at least VerifyParams::min_run matches along an edge (gaps of up to run_gap bridged)
  double match_share = 0.0;  ///< matched / samples (score counts in_runs / samples)
  PixelBox box;              ///< image box of the visible edge samples (px)
  /// The colour test (EdgeAligner::measure_leak; -1 when not measured): the share of colour
  /// samples just outside the silhouette that look like the colours just inside it.
  double leak = -1.0;
  int leak_samples = 0;  ///< outside samples of that test
};

/// \brief The local 6-DoF alignment of a pose to the image's edges (Gauss-Newton on the
/// distances, along the projected edge normals, from the model's edge samples to the strongest
/// gradient of the same orientation within a search range that shrinks over the iterations),
/// and the verification of a pose: the share of the model's visible edge samples that have a
/// gradient within `match_distance` along the normal and `match_angle` of the normal. Works on the
/// full-resolution gradients of a GradientPyramid; buffers are sized at construction.
class EdgeAligner {
 public:
  EdgeAligner(const model::Model& model, const geometry::PinholeCamera& cam, const DetectorParams& p);

  /// Refines `T_cam_obj` in place: first the distance along the line of sight is scanned
  /// (p.verify.depth_scan_steps steps of depth_scan_step either side, kept where most edge
  /// samples find a gradient), then p.verify.refine_iterations Gauss-Newton iterations; returns
  /// the number of iterations that moved the pose (0: too few edges matched).
  int refine(const GradientPyramid& g, geometry::SE3& T_cam_obj);
  /// Polishes a pose already close to the image's edges (a verified one): p.verify.polish_iterations
  /// Gauss-Newton iterations over up to p.verify.max_samples edge samples, each matched to the
  /// strongest aligned gradient within polish_range_px, placed by a parabola through its
  /// neighbours, Tukey-weighted. Returns the iterations that moved the pose.
  int polish(const GradientPyramid& g, geometry::SE3& T_cam_obj);
  /// Mean object-frame point of the edge samples visible at a pose (the model's centre of what
  /// the camera sees of it); `fallback` when none is.
  Eigen::Vector3d visible_centroid(const geometry::SE3& T_cam_obj, const Eigen::Vector3d& fallback);
  /// The edge test of a pose. An edge piece whose line the image continues past both of its ends
  /// (detect.verify.continued_*: an occluder's side or a background line the pose lies along)
  /// counts as unmatched.
  Verification verify(const GradientPyramid& g, const geometry::SE3& T_cam_obj);
  /// The colour test of a pose, into v.leak and v.leak_samples: colours sampled at a few pixels
  /// inside and outside along the silhouette edges (features::SilhouetteContrast). A pose on the
  /// object's outline, where the object differs from its surroundings, leaks little, occluded
  /// or not; a pose fitted to background edges, or nested in the object, leaks most samples.
  void measure_leak(const image::ColourView& colour, const geometry::SE3& T_cam_obj, Verification& v);
  /// \brief Two poses of nearly the same outline (a pose and its twin under a near symmetry)
  /// told apart by the edge samples where they differ: of each pose's samples farther than
  /// `px` from every sample of the other pose, the share that matches a gradient (as in verify).
  struct TwinShares {
    double a = 0.0, b = 0.0;  ///< matched share of a's distinctive samples, of b's
    int na = 0, nb = 0;       ///< distinctive samples of a, of b
    /// Mean distance (px) from a's distinctive samples, and from b's, to the centre of the
    /// nearest aligned edge along their normals (a blurred edge's plateau at its centroid),
    /// capped at kTwinReachPx (also when there is none). Only with `residuals` (else 0): one
    /// search along each sample's normal.
    double residual_a = 0.0, residual_b = 0.0;
  };
  static constexpr double kTwinReachPx = 4.0;
  TwinShares compare_twins(const GradientPyramid& g, const geometry::SE3& T_a, const geometry::SE3& T_b, double px,
                           bool residuals = false);

 private:
  /// The first detect.verify.refine_samples of the sample buffer.
  std::span<EdgeSample> refine_buffer();
  /// Share of edge samples with an aligned gradient within `range` px (no runs, loose angle).
  double loose_share(const GradientPyramid& g, const geometry::SE3& T, double range);
  /// Signed offset (px) along `n` of the best gradient within `range` px of `px`, or NaN.
  double search(const GradientPyramid& g, const Eigen::Vector2d& px, const Eigen::Vector2d& n, double range) const;
  /// The centroid (offset along the sample's normal, px) of the gradient plateau through offset k0
  /// (a motion-blurred edge) when it is at least p.verify.plateau_px wide, else k0.
  double plateau_centre(const GradientPyramid& g, const EdgeSample& s, int k0) const;
  /// Offset `t` (a search result) refined to a fraction of a pixel: the vertex of the parabola
  /// through the gradient along n at t - 1, t, t + 1.
  double parabola_peak(const GradientPyramid& g, const Eigen::Vector2d& px, const Eigen::Vector2d& n, double t) const;
  /// One Gauss-Newton step of the alignment over samples_[0, n): matches within `range` px, Huber
  /// or Tukey (tukey_px > 0) weights; false when fewer than 12 samples matched.
  bool align_step(const GradientPyramid& g, std::size_t n, double range, double tukey_px, bool subpixel,
                  geometry::SE3& T, geometry::Vector6d& delta);

  geometry::PinholeCamera cam_;
  VerifyParams p_;
  /// The frame's matching threshold (detect.verify.min_gradient*, relative to g.noise()).
  void set_threshold(const GradientPyramid& g);
  /// continued_[0, n): 1 for the samples of each edge piece of samples_[0, n) whose line the
  /// image continues past both of its ends (detect.verify.continued_*).
  void mark_continued(const GradientPyramid& g, std::size_t n);
  /// Sets (1) or clears (0) own_ in the 7x7 pixels about each of samples_[0, n).
  void paint_own(std::size_t n, std::uint8_t value);

  GradientThreshold threshold_;
  double min_sobel2_;  // squared threshold in Sobel units, of the last frame
  double cos_match_, cos_search_;
  EdgeProjector projector_;
  std::vector<EdgeSample> samples_;
  std::vector<std::uint8_t> matched_;     // verify: per sample of samples_, matched or not
  std::vector<std::uint8_t> continued_;   // verify: per sample, on a piece continued past both ends
  std::vector<std::uint8_t> own_;         // mark_continued: camera-sized, 1 near the pose's samples
  std::vector<Eigen::Vector2d> twin_px_;  // compare_twins: the first pose's sample positions
  std::vector<std::uint8_t> twin_matched_;
  std::vector<float> twin_residual_;      // compare_twins: the first pose's distances to the edge (px)
  // The distance (px, at most kTwinReachPx) from a sample to the centre of the nearest aligned edge.
  double edge_residual(const GradientPyramid& g, const EdgeSample& s) const;
  features::SilhouetteContrast contrast_;
};

}  // namespace v4r::detection
