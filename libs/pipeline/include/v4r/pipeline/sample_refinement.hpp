// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/image/image_view.hpp"
#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief One camera's view of the object for SampleRefiner: its predicted features, intrinsics,
/// image, the gradient threshold (grey levels per pixel) and where the camera sits relative to the
/// first view's camera (identity for the first).
struct SampleView {
  const scene::View* view = nullptr;
  const geometry::PinholeCamera* K = nullptr;
  image::ImageView grey;
  double threshold = 0.0;
  geometry::SE3 T_cam_first;
};

/// \brief The per-sample measurement of an object's pose (SampleRefineParams), beside the line
/// windows, over one or several views: each view's visible edges (tracked, side by side, or merged
/// with a neighbour: then its own model edge) and circles are sampled about `spacing_px` apart at
/// the start pose (further apart where a view's share of `max_samples` would not suffice); in each
/// Gauss-Newton iteration every sample is projected again and takes the strongest gradient aligned
/// with its normal within `range_px` along it (Sobel at those pixels only, placed to a fraction of
/// a pixel), Tukey-weighted with the same width. All views move one pose, that of the object in
/// the first view's camera. Buffers are sized by reserve(); refine() allocates nothing.
class SampleRefiner {
 public:
  static constexpr std::size_t kMaxViews = 8;  ///< views beyond are not sampled

  explicit SampleRefiner(const SampleRefineParams& p) : p_(p) {}

  /// The sample buffer (max_samples, shared by the views).
  void reserve();
  /// Refines `T_cam_obj` (the object in the first view's camera) in place from its value; a
  /// gradient counts from each view's threshold. False (T_cam_obj as given) when fewer than 12
  /// samples found a gradient or the step diverged.
  bool refine(const model::Model& model, std::span<const SampleView> views, geometry::SE3& T_cam_obj);
  /// One view: `grey` seen with `K`, gradients from `threshold`.
  bool refine(const model::Model& model, const scene::View& view, const geometry::PinholeCamera& K, const image::ImageView& grey, double threshold,
              geometry::SE3& T_cam_obj);
  /// Samples of the last refine().
  [[nodiscard]] std::size_t samples() const { return n_; }
  /// Gauss-Newton steps taken by the last refine().
  [[nodiscard]] int iterations() const { return iterations_; }

 private:
  struct Sample {
    Eigen::Vector3d X_obj;
    Eigen::Vector2d normal;  // unit normal of the projected edge at the start pose
    std::size_t view = 0;    // index into refine()'s views
  };
  /// Samples of the views' edges at T_cam_obj (first camera) into samples_; the spacing grows
  /// to keep each view to its share of max_samples.
  void take_samples(const model::Model& model, std::span<const SampleView> views, const geometry::SE3& T_cam_obj);
  /// Offset (px) along n of the strongest aligned gradient within range of px, or NaN; placed
  /// to a fraction of a pixel by a parabola through its neighbours. Gradients count from
  /// min_sobel2 (squared Sobel magnitude).
  [[nodiscard]] double search(const image::ImageView& g, const Eigen::Vector2d& px, const Eigen::Vector2d& n, double min_sobel2) const;

  SampleRefineParams p_;
  std::vector<Sample> samples_;
  std::size_t n_ = 0;
  int iterations_ = 0;
};

}  // namespace v4r::pipeline
