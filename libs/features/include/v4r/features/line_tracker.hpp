// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "v4r/image/colour_view.hpp"
#include "v4r/image/image_view.hpp"

namespace v4r::features {

/// \brief Parameters of the oriented line-tracking window (paper 3.1, 3.4, 4.1). The window has
/// a fixed size whatever the length of the edge, which bounds the cost of each feature.
struct LineTrackerParams {
  int rows = 16;               ///< samples along the edge (sub-image height); long edges are subsampled
  int half_width = 10;         ///< search range across the edge, pixels each side (sub-image width 2w+1)
  double end_margin = 0.1;     ///< fraction of the segment left out at each end (corners, junctions)
  /// Edge pixels must exceed the larger of two thresholds: this absolute floor (grey levels per
  /// pixel of the Prewitt gradient) and gradient_noise_factor times the window's noise level,
  /// which follows the image's noise and the texture of the faces (pure noise of deviation s:
  /// median |gradient| 0.67 s, threshold 2.7 s; two sharp edges in the window raise it to about
  /// 4 s). The noise level is the median |gradient|, or, when smaller, profile_noise_factor times
  /// the median deviation of the gradient from the profile across the window that its rows share:
  /// an edge blurred over most of the window is such a profile, and its own gradient would
  /// otherwise count as noise and hide it (0: off).
  float min_gradient = 3.0f;
  float gradient_noise_factor = 4.0f;
  float profile_noise_factor = 2.0f;
  /// A gradient peak on a plateau at least this many columns wide (a blurred edge: same sign,
  /// each column an edge pixel and at least half the peak) is located at the plateau's centroid
  /// and kept once, not at whichever column the noise raises (0: off). A sharp edge spans about 3
  /// columns, two sharp edges 2 px apart about 5: those keep their peaks.
  int ramp_min_width = 6;
  /// A pair followed as one (SearchRange::pair_span): a row's two edges of opposite sign make the
  /// pair's centre only when the weaker is at least this fraction of the stronger; else one edge
  /// shows and the other is lost in noise or in a face of the same brightness, and the row keeps
  /// its edges (a still mockup in noise was reported degraded for 4 frames without it; a factor
  /// 0.5 cost blurred plates, whose two sides differ).
  float pair_min_ratio = 0.25f;
  /// Inliers weaker than this fraction of the fitted line's mean edge strength are left out of
  /// the final fit (noise on the line where the edge itself is occluded).
  float min_relative_strength = 0.3f;
  /// Colour images: a window whose grey gradient shows no edge is searched again on the colour
  /// gradient (the three channels' gradients projected on their principal direction in the
  /// window), so that an edge between surfaces of equal brightness and different colour is found.
  bool use_colour_gradient = true;
  int max_candidates_per_row = 3;  ///< strongest local maxima kept per row
  int ransac_iterations = 40;  ///< RANSAC hypotheses
  double inlier_tolerance = 1.0;  ///< pixels: distance of an edge pixel from the line to count as inlier
  double min_inlier_ratio = 0.4;  ///< fraction of rows that must hold an inlier for the edge to count as found
  double max_angle = 0.35;     ///< radians: largest angle between the fitted line and the window axis
  std::uint32_t seed = 1;      ///< RANSAC random seed (deterministic)

  // Cue integration (paper 4.1, EPIC): an edge pixel of the object has the adjacent face's
  // appearance on its object side(s). Only sides marked LineTrackState::side[k].is_object are
  // checked and learned, so with no side marked the tracker behaves as without cues.
  bool use_cues = true;         ///< check candidates against the learned appearance of object sides
  int side_offset = 2;          ///< pixels from an edgel's peak column to the first side sample
  int side_width = 3;           ///< pixels sampled on each side of an edgel (across the edge)
  double appearance_k = 3.0;    ///< tolerance in standard deviations of the learned appearance
  float appearance_min_sigma = 6.0f;   ///< grey levels: floor of the intensity standard deviation
  float chroma_min_sigma = 0.02f;      ///< floor of the rg-chromaticity standard deviation (unitless)
  /// Colour only: intensity may also differ from the learned mean by this fraction of it (a
  /// shadow or a light change scales intensity but keeps chromaticity, which is checked strictly).
  float shadow_tolerance = 0.5f;
  double learning_rate = 0.3;   ///< weight of the current frame in the running mean / variance
  /// The appearance is learned from scratch (first frame, or after a cue fallback) only from a fit
  /// with at least this inlier ratio.
  double learn_min_inlier_ratio = 0.7;
  /// Colour only, silhouette edges (one object side): the other side's appearance is learned too,
  /// and when its chromaticity differed from the object side's by at least this many tolerances,
  /// a candidate whose outer band has the object side's chromaticity is rejected: a line of the
  /// object's own texture, with the object on both sides, is not its outline (0: off).
  double outside_distinct_k = 2.0;
  /// Colour only: when the learned cues leave no edge on the grey gradient, the colour gradient
  /// is searched with the cues before both are searched again without them (an outline between
  /// surfaces of equal brightness, beside a strong texture line of the object's own colour).
  bool colour_before_fallback = true;
  /// Colour, chromaticity-learned object sides: a fallback (the cues left no edge) still checks
  /// the chromaticity, and only the grey level is let go; with fallback_unchecked, a fallback
  /// that finds nothing so is searched once more without any check.
  bool fallback_keeps_chroma = true;
  bool fallback_unchecked = false;
};

/// \brief Appearance of one side of a tracked edge (paper 4.1): intensity and, on colour images,
/// chromaticity of a band of pixels beside each edge pixel, learned while tracking.
///
/// Channel 0 is the grey level (0..255); on colour images channels 1 and 2 are the normalised
/// chromaticities r = R / (R + G + B) and g = G / (R + G + B) (0..1), which a shadow leaves unchanged.
/// A colour-learned side tracked in a grey-only frame updates channel 0 and keeps 1 and 2.
struct SideAppearance {
  bool is_object = false;  ///< set by the caller: the object's surface lies on this side
  bool learned = false;    ///< mean / var hold a learned appearance
  float mean[3]{};         ///< mean of the per-edgel band means, per channel
  float var[3]{};          ///< variance of the per-edgel band means, per channel (units squared)
  int channels = 1;        ///< 1 = grey level only, 3 = grey level + rg chromaticity
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
  /// True when the candidates passing the appearance check could not make a found edge (e.g.
  /// after an abrupt change of light) and the edge was searched again without the check; the
  /// fields above describe that second search. A found fallback is less trustworthy: it may be a
  /// background edge when the object edge is occluded.
  bool cue_fallback = false;
  int cue_rejected = 0;       ///< candidate edge pixels discarded by the appearance check
  bool colour_gradient = false;  ///< found on the colour gradient (the grey one showed no edge)
  float threshold = 0.0f;     ///< gradient threshold the edge pixels had to pass (grey levels per pixel)
};

/// \brief Per-feature state the tracker keeps between frames (the window follows the feature).
struct LineTrackState {
  int polarity = 0;  ///< 0 = unknown; else the sign of the edge's gradient, preferred in later frames
  /// Appearance of the two sides of the edge: [0] = the -normal side (window columns < 0), [1] =
  /// the +normal side, the normal being the prediction's direction a->b turned by +90 degrees
  /// (n = (-d.y, d.x)). The caller marks is_object (both for an edge between two visible faces);
  /// the tracker learns mean / var.
  SideAppearance side[2];
  /// Colour-gradient search: the principal colour direction (B, G, R; unit) of the last edge found
  /// on the colour gradient, which fixes the sign of the projected gradient, and that edge's polarity.
  float colour_axis[3]{};
  int colour_polarity = 0;
  /// Silhouette edges: appearance of the side without the object (the background), learned like
  /// the object side; outside_side is the side it was learned on (-1: none), and a change of it
  /// (the edge no longer a silhouette, or seen from the other side) forgets it.
  SideAppearance outside;
  int outside_side = -1;
};

/// \brief Offsets across a tracking window (pixels) where an edge may be found.
struct SearchRange {
  double lo = -1e9, hi = 1e9;
  /// > 0: the window follows a pair of close parallel edges as one (a thin plate, its two edges
  /// closer than the window can split) and measures the centre between them: per row, the
  /// strongest edge of each sign, when no farther apart than this (pixels) and of comparable
  /// strength (LineTrackerParams::pair_min_ratio), give their midpoint.
  /// Motion blur across a thin plate pushes each of its edges outward by half the blur (each
  /// edge's gradient plateau is the plate's width wide, at the blur's ends); their midpoint stays
  /// on the plate's mid-line. A row without both keeps its edges. The state's polarity and learned
  /// sides are neither used nor updated (they are the single edge's). On a colour image, a window
  /// whose grey gradient shows no pair searches the colour gradient (a plate of its
  /// surroundings' brightness).
  double pair_span = 0.0;
};

/// \brief Finds a straight edge near a predicted segment.
///
/// The predicted segment is resampled into a fixed-size oriented sub-image (rows along the edge,
/// columns across it) so the edge is vertical; a 1-D Prewitt mask gives the gradient across;
/// each row keeps its strongest local maxima as edge pixels (sub-pixel by parabola); RANSAC fits
/// the line. Buffers are allocated once in the constructor: track() allocates nothing.
///
/// Cues (paper 4.1): a candidate edge pixel is kept only if the band of pixels on each learned
/// object side (side_offset .. side_offset + side_width - 1 pixels across, same row) matches the
/// learned appearance of that side: grey level within k * max(sigma, appearance_min_sigma); with
/// a colour image, rg chromaticity within k * max(sigma, chroma_min_sigma) and the grey level with
/// the looser shadow_tolerance as well. Strong background edges are thus discarded instead of
/// fitted. After a fit the object sides' appearance is updated from the inliers.
class LineTracker {
 public:
  explicit LineTracker(const LineTrackerParams& params = {});

  /// Track an edge near `predicted` (pixels) in the grey image `grey`. `state` carries polarity
  /// and side appearance between frames and is updated on success. `colour` (optional, same
  /// size as `grey`, of which `grey` is the grey conversion) adds chromaticity to the cues; a
  /// colour view of another size is ignored. After a found fallback (cue_fallback) the object
  /// sides are relearned from scratch if inlier_ratio >= learn_min_inlier_ratio; a caller that
  /// then rejects the measurement (e.g. as a pose outlier) may clear side[k].learned. Never
  /// throws; a window that leaves the image is sampled clamped and its rows outside the image are
  /// ignored. `range` limits where the edge is searched across the window: offsets (pixels,
  /// along the normal (-d.y, d.x) of the direction d = b - a) from range.lo to range.hi, within
  /// the window's half width; a window split from a neighbouring parallel edge uses it.
  LineMeasurement track(const image::ImageView& grey, const Segment2& predicted, LineTrackState& state,
                        const image::ColourView* colour = nullptr, SearchRange range = {});

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
    int col;         // window column of the gradient peak (0 .. 2w)
  };
  // Appearance check of one side, prepared once per track() from the learned state.
  struct SideCheck {
    bool active = false;
    bool chroma = false;       // compare chromaticity (colour image and a colour-learned side)
    float mean[3]{};
    float tol[3]{};            // tolerances of the three channels (chroma: before darkness scaling)
  };
  struct LineFit { double u0 = 0.0, s = 0.0; };  // u = u0 + s * v (window coordinates, pixels)

  std::uint32_t next_random();
  // Step 3: edgels of every valid row from grad_; with `cues`, candidates failing the appearance
  // check are discarded. Fills edgels_, row_count_, pool_, pool_cum_; returns the pool size.
  int extract_edgels(int want, bool cues, int* rejected);
  // Replaces grad_ by the colour gradient of the valid rows, projected on its principal direction
  // in the window (sign from state.colour_axis); sets thr_. False when it has no direction.
  bool colour_gradient(const LineTrackState& state, float axis[3]);
  // Edgels, RANSAC and measurement with the appearance check when `cues` (and without it when
  // that finds nothing): steps 3-5 on the current grad_.
  void detect(int want, bool cues, int valid_rows, LineMeasurement& m, bool allow_fallback);
  // Step 2: grad_ from patch_ (central differences across) for the valid rows; sets thr_.
  void grey_gradient();
  // Steps 4-5: RANSAC and refinement over the pool; fills m (found, line, ...) and last_inliers_;
  // leaves the final inliers in inlier_idx_[0 .. m.inliers).
  void fit_pool(int pool_size, int valid_rows, LineMeasurement& m);
  // Mean grey level of the side band of the edgel at (row, col); false when no sample is inside.
  bool grey_band(int row, int col, int side, float* grey) const;
  // Mean rg chromaticity of the side band (colour image only); false when outside or too dark.
  bool chroma_band(int row, int col, int side, float rg[2]) const;
  bool appearance_ok(int row, int col) const;
  // Prepares outside_check_ from the learned object and outside appearance (silhouette edges).
  void prepare_outside_check(const LineTrackState& state);
  // Updates the appearance of the object sides from the inliers of `m` (in inlier_idx_).
  void learn_sides(LineTrackState& state, const LineMeasurement& m, bool reset) const;
  // Updates one appearance from the bands on side `side` of the inliers of `m`.
  void learn_band(SideAppearance& a, int side, const LineMeasurement& m, bool reset) const;
  int score_line(const LineFit& line, int sign, float* strength_sum);  // fills inlier_idx_, returns count
  bool fit_inliers(int count, LineFit* out) const;

  LineTrackerParams p_;
  int cols_ = 0;                 // 2w+1
  std::vector<float> patch_;     // rows x (2w+1) sampled intensities, smoothed along the edge
  std::vector<float> grad_;      // rows x (2w+1) gradient across
  std::vector<unsigned char> row_valid_;
  std::vector<unsigned char> col_inside_;  // 2w+1: the current row's samples all inside the image
  std::vector<int> sample_off_;      // 3 x (2w+1): byte offset of each sample's top-left pixel
  std::vector<float> sample_ax_, sample_ay_, sample_val_;  // 3 x (2w+1): its weights and value
  std::vector<float> colour_row_;  // 3 x (2w+1): one row's smoothed B, G, R samples (colour gradient); scratch of window_threshold
  std::vector<float> colour_grad_;  // rows x (2w+1) x 3: gradient across, per channel
  std::vector<double> row_v_;    // rows: position of each row along the axis (pixels)
  std::vector<Eigen::Vector2d> row_centre_;  // rows: window centre point of each row (pixels)
  std::vector<Edgel> edgels_;    // rows x max_candidates_per_row, row-major slots
  std::vector<int> row_count_;   // rows: edgels held in each row's slots
  std::vector<int> pool_;        // flat indices of all edgels (RANSAC sampling)
  std::vector<float> pool_cum_;  // prefix sums of the pool's strengths (weighted sampling)
  std::vector<int> inlier_idx_;  // rows: edgel index of each inlier (at most one per row)
  std::vector<Eigen::Vector2d> last_inliers_;
  std::uint32_t rng_ = 1;
  // Context of the current track() call (set at its start; no ownership).
  image::ImageView img_;
  int col_lo_ = 0, col_hi_ = 0;  // columns where edgels may be taken (from the SearchRange)
  float thr_ = 0.0f;             // gradient threshold of the current grad_ (see min_gradient)
  const image::ColourView* colour_ = nullptr;
  Eigen::Vector2d d_ = Eigen::Vector2d::Zero(), n_ = Eigen::Vector2d::Zero();  // window axis, normal
  SideCheck check_[2];
  bool chroma_only_ = false;  // appearance_ok checks chromaticity only (a fallback's search)
  float pair_span_ = 0.0f;    // SearchRange::pair_span of the current track() call
  bool pairs_only_ = false;   // a pair window on the colour gradient: rows without a pair give no edgel
  // Silhouette edges (outside_distinct_k): candidates whose band on side `side` has the object
  // side's chromaticity (mean, tol) are rejected.
  struct OutsideCheck {
    bool active = false;
    int side = 0;
    float mean[2]{};
    float tol[2]{};
  } outside_check_;
};

}  // namespace v4r::features
