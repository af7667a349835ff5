// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <vector>

#include "v4r/geometry/se3.hpp"

namespace v4r::pipeline {

/// \brief Accuracy of an estimated pose sequence against ground truth.
struct AccuracyStats {
  int frames = 0;
  double mean_translation_m = 0.0, max_translation_m = 0.0;
  double mean_rotation_deg = 0.0, max_rotation_deg = 0.0;
  int successes = 0;  ///< frames with translation error < success_translation and rotation < success_rotation
  [[nodiscard]] double success_ratio() const { return frames > 0 ? static_cast<double>(successes) / frames : 0.0; }
};

/// Compares estimates with ground truth frame by frame (the shorter length is used).
/// A success is a frame within `success_translation_m` metres and `success_rotation_deg` degrees.
AccuracyStats evaluate(const std::vector<geometry::SE3>& estimated, const std::vector<geometry::SE3>& truth,
                       double success_translation_m = 0.05, double success_rotation_deg = 5.0);

/// Median and 99th percentile of a sample (copied, then partially sorted).
struct Percentiles {
  double median = 0.0, p99 = 0.0, mean = 0.0, max = 0.0;
};
Percentiles percentiles(std::vector<double> v);

}  // namespace v4r::pipeline
