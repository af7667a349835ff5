// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <vector>

#include "v4r/estimation/pose_solver.hpp"

namespace v4r::pipeline {

/// \brief Which feature of which view an observation came from (to hand the solver's inlier
/// verdicts back).
struct FeatureRef {
  std::uint16_t view = 0;     ///< index into Object::views
  std::uint32_t feature = 0;  ///< index into View::lines or View::arcs
};

/// \brief The observations of one object from every camera that sees it, ready for one solve:
/// measurement units append, the solver reads them and writes the inlier flags. Capacity is
/// reserved up front (reserve()); the per-frame path then allocates nothing.
struct ObservationBuffer {
  std::vector<estimation::SolveCamera> cameras;  ///< one per view in the solve; observation.camera indexes it
  std::vector<estimation::LineObservation> lines;
  std::vector<FeatureRef> line_refs;
  std::vector<std::uint8_t> line_inliers;
  std::vector<estimation::PointObservation> points;  ///< junctions
  std::vector<std::uint8_t> point_inliers;
  std::vector<estimation::CircleObservation> circles;  ///< ellipse edge points
  std::vector<FeatureRef> circle_refs;
  std::vector<std::uint8_t> circle_inliers;
  int tangent_junctions = 0;  ///< of `points`, line-arc junctions with a common tangent

  void reserve(std::size_t cameras_, std::size_t lines_, std::size_t points_, std::size_t circles_) {
    cameras.reserve(cameras_);
    lines.reserve(lines_);
    line_refs.reserve(lines_);
    line_inliers.reserve(lines_);
    points.reserve(points_);
    point_inliers.reserve(points_);
    circles.reserve(circles_);
    circle_refs.reserve(circles_);
    circle_inliers.reserve(circles_);
  }
  void clear() {
    cameras.clear();
    lines.clear();
    line_refs.clear();
    points.clear();
    circles.clear();
    circle_refs.clear();
    tangent_junctions = 0;
  }
  /// Observations counted as the cycle counts them: an ellipse's edge points count a quarter each.
  [[nodiscard]] int count() const {
    return static_cast<int>(lines.size() + points.size() + circles.size() / 4);
  }
  /// Observations that fix the pose independently: lines and circles (4 edge points count one),
  /// not junctions, which are intersections of the same lines (CycleParams::min_lines).
  [[nodiscard]] int independent_count() const { return static_cast<int>(lines.size() + circles.size() / 4); }
  /// The same over the observations the last solve kept (line_inliers, circle_inliers).
  [[nodiscard]] int independent_inliers() const {
    long n = 0, c = 0;
    for (const std::uint8_t f : line_inliers) n += f != 0 ? 1 : 0;
    for (const std::uint8_t f : circle_inliers) c += f != 0 ? 1 : 0;
    return static_cast<int>(n + c / 4);
  }
  /// Marks every observation an inlier (before a solve).
  void reset_inliers() {
    line_inliers.assign(lines.size(), 1);
    point_inliers.assign(points.size(), 1);
    circle_inliers.assign(circles.size(), 1);
  }
};

}  // namespace v4r::pipeline
