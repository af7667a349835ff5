// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/evaluation.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace v4r::pipeline {

AccuracyStats evaluate(const std::vector<geometry::SE3>& estimated, const std::vector<geometry::SE3>& truth,
                       double success_translation_m, double success_rotation_deg) {
  AccuracyStats s;
  const std::size_t n = std::min(estimated.size(), truth.size());
  for (std::size_t i = 0; i < n; ++i) {
    const double et = (estimated[i].translation() - truth[i].translation()).norm();
    const double er = geometry::rotation_angle_between(estimated[i], truth[i]) * 180.0 / M_PI;
    s.mean_translation_m += et;
    s.mean_rotation_deg += er;
    s.max_translation_m = std::max(s.max_translation_m, et);
    s.max_rotation_deg = std::max(s.max_rotation_deg, er);
    if (et < success_translation_m && er < success_rotation_deg) ++s.successes;
  }
  s.frames = static_cast<int>(n);
  if (n > 0) {
    s.mean_translation_m /= static_cast<double>(n);
    s.mean_rotation_deg /= static_cast<double>(n);
  }
  return s;
}

Percentiles percentiles(std::vector<double> v) {
  Percentiles p;
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  auto at = [&](double q) {
    const double idx = q * static_cast<double>(v.size() - 1);
    const auto lo = static_cast<std::size_t>(std::floor(idx));
    const std::size_t hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (idx - static_cast<double>(lo)) * (v[hi] - v[lo]);
  };
  p.median = at(0.5);
  p.p99 = at(0.99);
  p.mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  p.max = v.back();
  return p;
}

}  // namespace v4r::pipeline
