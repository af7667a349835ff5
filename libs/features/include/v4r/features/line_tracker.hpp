// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "v4r/image/image_view.hpp"

namespace v4r::features {

/// \brief Parameters of the oriented line-tracking window (paper 3.1, 3.4, 4.1). The window has
/// a fixed size whatever the length of the edge, which bounds the cost of each feature.
struct LineTrackerParams {
  int rows = 24;               ///< samples along the edge (sub-image height); long edges are subsampled
  int half_width = 10;         ///< search range across the edge, pixels each side (sub-image width 2w+1)
  double end_margin = 0.1;     ///< fraction of the segment left out at each end (corners, junctions)
  float min_gradient = 8.0f;   ///< minimum |Prewitt gradient| (grey levels per pixel) of an edge pixel
  int max_candidates_per_row = 3;  ///< strongest local maxima kept per row
  int ransac_iterations = 40;  ///< RANSAC hypotheses
  double inlier_tolerance = 1.0;  ///< pixels: distance of an edge pixel from the line to count as inlier
  double min_inlier_ratio = 0.4;  ///< fraction of rows that must hold an inlier for the edge to count as found
  double max_angle = 0.35;     ///< radians: largest angle between the fitted line and the window axis
  std::uint32_t seed = 1;      ///< RANSAC random seed (deterministic)
};

/// \brief A 2-D segment in pixel coordinates.
struct Segment2 {
  Eigen::Vector2d a = Eigen::Vector2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
};

/// \brief Result of tracking one edge in one window.
struct LineMeasurement {
  /// True when the edge was found. When false, the fields below may still describe the best
  /// rejected fit (for diagnostics), or stay zero when no fit was possible.
  bool found = false;
  /// Two points of the fitted image line (pixels), at the window's first and last rows: the
  /// observed line is the infinite line through them; a->b keeps the direction of the prediction.
  Segment2 line;
  double offset_px = 0.0;     ///< signed mean displacement of the fitted line from the prediction across the window
  double inlier_ratio = 0.0;  ///< rows with an inlier edge pixel / rows sampled
  int inliers = 0;            ///< edge pixels on the fitted line
  double rms_px = 0.0;        ///< RMS distance of the inliers from the fitted line (pixels)
  int polarity = 0;           ///< sign of the gradient across the edge (left->right in window), +1/-1
};

/// \brief Per-feature state the tracker keeps between frames (the window follows the feature).
struct LineTrackState {
  int polarity = 0;  ///< 0 = unknown; else the sign of the edge's gradient, preferred in later frames
};

/// \brief Finds a straight edge near a predicted segment.
///
/// The predicted segment is resampled into a fixed-size oriented sub-image (rows along the edge,
/// columns across it) so the edge is vertical; a 1-D Prewitt mask gives the gradient across;
/// each row keeps its strongest local maxima as edge pixels (sub-pixel by parabola); RANSAC fits
/// the line. Buffers are allocated once in the constructor: track() allocates nothing.
class LineTracker {
 public:
  explicit LineTracker(const LineTrackerParams& params = {});

  /// Track an edge near `predicted` (pixels). `state` carries polarity between frames and is
  /// updated on success. Never throws; a window that leaves the image is sampled clamped and
  /// its rows outside the image are ignored.
  LineMeasurement track(const image::ImageView& img, const Segment2& predicted, LineTrackState& state);

  [[nodiscard]] const LineTrackerParams& params() const { return p_; }
  /// Edge pixels of the last call (pixels), for overlays: inliers of the fit.
  [[nodiscard]] const std::vector<Eigen::Vector2d>& last_inliers() const { return last_inliers_; }

 private:
  struct Edgel {
    float u;         // column offset from the window axis (pixels, along the normal)
    float v;         // position along the window axis (pixels, 0 at the window centre)
    float strength;  // |gradient| at the edgel (grey levels per pixel)
    int sign;        // +1 / -1: sign of the gradient along the normal
    int row;         // window row index
  };
  struct LineFit { double u0 = 0.0, s = 0.0; };  // u = u0 + s * v (window coordinates, pixels)

  std::uint32_t next_random();
  int score_line(const LineFit& line, int sign, float* strength_sum);  // fills inlier_idx_, returns count
  bool fit_inliers(int count, LineFit* out) const;

  LineTrackerParams p_;
  int cols_ = 0;                 // 2w+1
  std::vector<float> patch_;     // rows x (2w+1) sampled intensities, smoothed along the edge
  std::vector<float> grad_;      // rows x (2w+1) gradient across
  std::vector<unsigned char> row_valid_;
  std::vector<unsigned char> col_inside_;  // 2w+1: the current row's samples all inside the image
  std::vector<double> row_v_;    // rows: position of each row along the axis (pixels)
  std::vector<Eigen::Vector2d> row_centre_;  // rows: window centre point of each row (pixels)
  std::vector<Edgel> edgels_;    // rows x max_candidates_per_row, row-major slots
  std::vector<int> row_count_;   // rows: edgels held in each row's slots
  std::vector<int> pool_;        // flat indices of all edgels (RANSAC sampling)
  std::vector<float> pool_cum_;  // prefix sums of the pool's strengths (weighted sampling)
  std::vector<int> inlier_idx_;  // rows: edgel index of each inlier (at most one per row)
  std::vector<Eigen::Vector2d> last_inliers_;
  std::uint32_t rng_ = 1;
};

}  // namespace v4r::features
