// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "v4r/image/image_view.hpp"

namespace v4r::features {

/// \brief Parameters of the elliptic-arc tracker (paper 3.2): tracking lines of height one pixel
/// placed across the predicted curve, then a robust ellipse fit of the edge points found on them.
/// The cost per feature is bounded by max_samples, whatever the size of the ellipse.
struct EllipseTrackerParams {
  int max_samples = 48;            ///< capacity: most tracking lines per ellipse (more samples are subsampled)
  int half_length = 8;             ///< pixels searched each side of the predicted curve along its normal
  float min_gradient = 8.0f;       ///< minimum |gradient| (grey levels per pixel) of an edge point
  int max_candidates_per_line = 3; ///< strongest local maxima kept per tracking line (clutter)
  double max_edge_angle = 0.6;     ///< radians: largest angle between the image gradient and the sample normal
  int ransac_iterations = 60;      ///< RANSAC hypotheses (fewer when the inlier ratio is high)
  double inlier_tolerance = 1.0;   ///< pixels: Sampson distance of an edge point to the ellipse
  double min_inlier_ratio = 0.4;   ///< of the samples whose search line lies inside the image
  std::uint32_t seed = 1;          ///< RANSAC random seed (deterministic)
};

/// \brief A point of the predicted (projected, distorted) circle and the unit normal of the curve
/// there, pixels. Normals should be oriented consistently (e.g. all outwards) so that the edge has
/// one polarity along them.
struct CurveSample {
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
  Eigen::Vector2d normal = Eigen::Vector2d::UnitX();
};

/// \brief Ellipse as centre, semi-axes a >= b > 0 (pixels) and angle of the a-axis from the image
/// x axis (radians, in (-pi/2, pi/2]); also as a conic.
struct Ellipse2 {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double a = 0.0;
  double b = 0.0;
  double angle = 0.0;

  /// Coefficients (A, B, C, D, E, F) of A x^2 + B xy + C y^2 + D x + E y + F = 0 (pixels),
  /// normalised to unit Euclidean norm with A + C > 0, so the conic is negative inside. Zero when
  /// the ellipse is degenerate (a or b not positive and finite).
  [[nodiscard]] Eigen::Matrix<double, 6, 1> conic() const;
};

/// \brief Result of tracking one ellipse (or elliptic arc) in one image.
struct EllipseMeasurement {
  /// True when the ellipse was found. When false, the other fields may describe the best
  /// rejected fit (diagnostics) or stay zero when no fit was possible.
  bool found = false;
  Ellipse2 ellipse;           ///< fitted ellipse (pixels)
  int inliers = 0;            ///< tracking lines whose edge point lies on the fitted ellipse
  double inlier_ratio = 0.0;  ///< inliers / tracking lines whose sample point lies inside the image
  double rms_px = 0.0;        ///< RMS Sampson distance of the inliers from the fitted ellipse (pixels)
  int polarity = 0;           ///< sign of the gradient along the sample normals at the inliers, +1/-1
};

/// \brief Per-feature state the tracker keeps between frames.
struct EllipseTrackState {
  int polarity = 0;  ///< 0 = unknown; else the sign of the gradient along the sample normals, learned
};

/// \brief Finds an ellipse (or elliptic arc) near a predicted curve given as samples with normals.
///
/// Algorithm (paper 3.2):
/// 1. Prediction: the predicted ellipse is recovered from the samples by an algebraic conic fit
///    to their points and normals (Hartley-normalised; exact for samples of an ellipse, well-posed
///    for arcs thanks to the normals). Samples far from any ellipse make the call fail.
/// 2. Edge points: each sample gets a tracking line along its normal (offsets -L..L, L =
///    half_length), averaged with the two parallel lines 1 px away along the tangent; the
///    strongest local maxima of the central-difference gradient (|g| >= min_gradient, sign fixed
///    by the learned polarity, image gradient within max_edge_angle of the normal) are refined to
///    sub-pixel by a parabola. On the inner side a line stops at 0.7 x the predicted radius of
///    curvature, where neighbouring lines would start to cross.
/// 3. RANSAC: each hypothesis is the ellipse through 5 edge points of one polarity on distinct
///    lines (drawn with probability proportional to gradient strength), solved by Gauss-Newton on
///    their Sampson distances starting from the prediction with a weak Gaussian prior towards it,
///    so that points on a short arc still give a well-posed ellipse. Non-ellipses and ellipses
///    whose centre moved more than 2L or whose axes changed by more than 30 % are rejected.
///    Inliers: per line, the candidate nearest the ellipse within inlier_tolerance (Sampson
///    distance) whose gradient is within 20 degrees of the ellipse normal. Hypotheses are ranked
///    by the MSAC utility; a new best one is refitted on its inliers (local optimisation); the
///    iteration count adapts to the inlier ratio.
/// 4. Refinement: Gauss-Newton on all inliers, inliers recomputed, while the utility improves;
///    then the tolerance shrinks to 3.5 robust standard deviations of the residuals (at least
///    0.4 x inlier_tolerance) and the last fit weighs the points by that standard deviation.
///
/// Arcs: the fit is the MAP estimate with the prior (centre sigma L pixels, shape sigma 15 % of the
/// size). Wherever the edge points constrain the ellipse (full ellipse, half arc) the prior is
/// negligible; in the directions a short arc cannot observe it keeps the ellipse near the
/// prediction, while the fit still passes through the arc's edge points (reported as inliers).
///
/// Found when at least 6 inliers, inlier_ratio >= min_inlier_ratio and the fit passes the
/// prediction gate. Buffers are allocated in the constructor: track() allocates nothing.
class EllipseTracker {
 public:
  explicit EllipseTracker(const EllipseTrackerParams& params = {});

  /// Track an ellipse near the `predicted` curve samples (pixels). More samples than
  /// max_samples: an evenly spaced subset is used. `state` carries the polarity between frames
  /// and is updated on success. Never throws; degenerate input (fewer than 6 samples, non-finite
  /// or zero normals, samples not on an ellipse, empty image) gives found = false. Tracking lines
  /// whose sample point lies outside the image are skipped; the parts of a line outside the image
  /// yield no edge points.
  EllipseMeasurement track(const image::ImageView& img, std::span<const CurveSample> predicted,
                           EllipseTrackState& state);

  /// Inlier edge points of the last call (pixels), for overlays and pose estimation.
  [[nodiscard]] const std::vector<Eigen::Vector2d>& last_inliers() const { return last_inliers_; }
  /// Index into the last call's `predicted` of the sample of each inlier (same order as last_inliers()).
  [[nodiscard]] const std::vector<int>& last_inlier_samples() const { return last_inlier_samples_; }
  /// The parameters in use (sanitised: sizes clamped, NaN replaced by defaults).
  [[nodiscard]] const EllipseTrackerParams& params() const { return p_; }

 private:
  /// Ellipse in normalised coordinates: (x - c)^T S (x - c) = 1 with x = (pixel - origin) / scale;
  /// v = (cx, cy, S11, S12, S22).
  using Params5 = Eigen::Matrix<double, 5, 1>;
  struct Candidate {
    Eigen::Vector2d q;  // edge point, normalised coordinates
    Eigen::Vector2d g;  // unit image gradient direction at the edge point
    float strength;     // |gradient| (grey levels per pixel)
    int sign;           // +1 / -1: sign of the gradient along the sample normal
    int line;           // tracking line index
  };

  std::uint32_t next_random();
  bool predict_ellipse(int n);
  void limit_line(int i);
  void search_line(const image::ImageView& img, int i, int want_sign);
  struct Score {
    int count = 0;        // inlier lines
    double sq_px = 0.0;   // sum of the inliers' squared Sampson distances (pixels^2)
    double utility = 0.0; // MSAC: sum over inliers of 1 - (d / tolerance)^2
  };
  Score score(const Params5& v, int sign, double tolerance_px);  // fills inlier_idx_
  bool fit(const int* idx, int count, int iterations, double sigma_px, Params5* v) const;
  bool gate(const Params5& v) const;
  Ellipse2 to_pixels(const Params5& v) const;

  EllipseTrackerParams p_;
  int cols_ = 0;                            // 2L+5
  float tan_max_edge_ = 0.0f;               // tan(max_edge_angle)
  std::vector<int> sample_index_;           // max_samples: index into `predicted` of each line
  std::vector<Eigen::Vector2d> line_p_;     // max_samples: sample point (pixels)
  std::vector<Eigen::Vector2d> line_n_;     // max_samples: unit normal
  std::vector<double> line_lo_, line_hi_;   // max_samples: offsets searched along the normal (pixels)
  std::vector<float> profile_;              // 2L+5 smoothed intensities of the current line
  std::vector<float> tangential_;           // 2L+5 gradient along the tangent (grey levels per pixel)
  std::vector<float> grad_;                 // 2L+5 gradient along the normal
  std::vector<unsigned char> inside_;       // 2L+5: samples of the current line inside the image
  std::vector<Candidate> cand_;             // max_samples x max_candidates_per_line, line-major slots
  std::vector<int> cand_count_;             // max_samples
  std::vector<int> pool_;                   // candidate indices, positive signs first (RANSAC sampling)
  std::vector<float> pool_cum_;             // prefix sums of their strengths
  std::vector<int> inlier_idx_;             // max_samples: candidate index of each inlier
  std::vector<int> best_idx_;               // max_samples: inliers of the best hypothesis
  std::vector<double> residual_;            // max_samples: |Sampson distance| of the inliers (scratch)
  std::vector<Eigen::Vector2d> last_inliers_;
  std::vector<int> last_inlier_samples_;
  Eigen::Vector2d origin_ = Eigen::Vector2d::Zero();  // pixels: predicted centre
  double scale_ = 1.0;                                // pixels per normalised unit
  Params5 prior_ = Params5::Zero();                   // predicted ellipse, normalised
  Ellipse2 predicted_;                                // predicted ellipse, pixels
  std::uint32_t rng_ = 1;
};

}  // namespace v4r::features
