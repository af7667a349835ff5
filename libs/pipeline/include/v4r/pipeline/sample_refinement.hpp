// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstddef>
#include <vector>

#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/image/image_view.hpp"
#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief The per-sample measurement of a view's pose (SampleRefineParams), beside the line
/// windows: the view's visible edges (tracked, side by side, or merged with a neighbour: then
/// its own model edge) and circles are sampled about
/// `spacing_px` apart at the start pose; in each Gauss-Newton iteration every sample is projected
/// again and takes the strongest gradient aligned with its normal within `range_px` along it
/// (Sobel at those pixels only, placed to a fraction of a pixel), Tukey-weighted with the same
/// width. Buffers are sized by reserve(); refine() allocates nothing.
class SampleRefiner {
 public:
  explicit SampleRefiner(const SampleRefineParams& p) : p_(p) {}

  /// The sample buffer (max_samples).
  void reserve();
  /// Refines `T_cam_obj` in place from its value, on `grey` with `K`; a gradient counts from
  /// `threshold` grey levels per pixel. False (T_cam_obj as given) when fewer than 12 samples
  /// found a gradient or the step diverged.
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
  };
  /// Samples of the view's edges at T into samples_ (the spacing grows to keep max_samples).
  void take_samples(const model::Model& model, const scene::View& view, const geometry::PinholeCamera& K,
                    const geometry::SE3& T);
  /// Offset (px) along n of the strongest aligned gradient within range of px, or NaN; placed
  /// to a fraction of a pixel by a parabola through its neighbours.
  [[nodiscard]] double search(const image::ImageView& g, const Eigen::Vector2d& px, const Eigen::Vector2d& n) const;

  SampleRefineParams p_;
  std::vector<Sample> samples_;
  std::size_t n_ = 0;
  int iterations_ = 0;
  double min_sobel2_ = 0.0;
};

}  // namespace v4r::pipeline
