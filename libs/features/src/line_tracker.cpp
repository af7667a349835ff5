// v4r - robust model-based object tracking. MIT licence.
#include "v4r/features/line_tracker.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <Eigen/Eigenvalues>

namespace v4r::features {

namespace {

constexpr double kMinSegmentLength = 3.0;  // pixels: shorter predictions are degenerate
constexpr double kRowMargin = 1.0;         // pixels: a row centre must lie this far inside the image
constexpr int kMinInliers = 3;             // a line needs at least this many inlier rows
constexpr std::uint32_t kDefaultSeed = 0x9E3779B9u;  // xorshift state must not be zero
// RANSAC stops once a pair of inliers has been drawn with this probability (counting inlier
// ratios over the whole pool, both polarities: conservative, the draw favours strong edgels).
constexpr double kRansacConfidence = 0.999;

constexpr double kInsideMargin = 0.01;     // pixels: keeps x0 + 1, y0 + 1 of a bilinear sample inside
constexpr float kMinChromaSum = 30.0f;     // grey levels: mean R + G + B below which rg chromaticity is noise
constexpr float kMaxDarkScale = 4.0f;      // largest widening of the chroma tolerance on a darkened band

/// Median of |value| over a window, from a histogram of 0.5 grey/px bins (the last bin holds
/// everything above).
class GradientHistogram {
 public:
  void add(float g) {
    const int b = static_cast<int>(std::abs(g) * kPerUnit);
    ++bins_[b < kBins - 1 ? (b >= 0 ? b : kBins - 1) : kBins - 1];  // (NaN: last bin)
    ++count_;
  }
  [[nodiscard]] float median() const {
    long seen = 0;
    for (int b = 0; b < kBins; ++b) {
      seen += bins_[b];
      if (2 * seen >= count_) return (static_cast<float>(b) + 0.5f) / kPerUnit;
    }
    return 0.0f;
  }

 private:
  static constexpr int kBins = 128;
  static constexpr float kPerUnit = 2.0f;  // bins per grey level per pixel
  int bins_[kBins] = {};
  long count_ = 0;
};

/// Gradient threshold of a window of rows x cols gradients (see LineTrackerParams::min_gradient
/// and profile_noise_factor). Two estimates of the window's noise and texture level: the median
/// |gradient|, and profile_noise_factor times the median deviation of the gradient from its
/// column's mean over the rows (the across-profile the rows share: an edge, sharp or blurred over
/// most of the window, which the first estimate would count as noise). The smaller is used.
/// `profile` holds cols floats (scratch).
float window_threshold(const LineTrackerParams& p, const float* grad, const unsigned char* row_valid,
                       const unsigned char* inside, int rows, int cols, float* profile) {
  GradientHistogram level, deviation;
  for (int j = 0; j < cols; ++j) profile[j] = 0.0f;
  int n = 0;
  for (int i = 0; i < rows; ++i) {
    if (!row_valid[i]) continue;
    const float* g = grad + static_cast<std::size_t>(i) * cols;
    const unsigned char* in = inside + static_cast<std::size_t>(i) * cols;
    for (int j = 1; j < cols - 1; ++j) {
      if (!in[j - 1] || !in[j + 1]) continue;
      level.add(g[j]);
      profile[j] += g[j];
    }
    ++n;
  }
  float noise = level.median();
  if (p.profile_noise_factor > 0.0f && n > 1) {
    // Column means over the valid rows (a column outside the image in some rows: its mean is
    // lowered towards 0 there, which only raises the deviation, i.e. the estimate stays safe).
    for (int j = 0; j < cols; ++j) profile[j] /= static_cast<float>(n);
    for (int i = 0; i < rows; ++i) {
      if (!row_valid[i]) continue;
      const float* g = grad + static_cast<std::size_t>(i) * cols;
      const unsigned char* in = inside + static_cast<std::size_t>(i) * cols;
      for (int j = 1; j < cols - 1; ++j)
        if (in[j - 1] && in[j + 1]) deviation.add(g[j] - profile[j]);
    }
    noise = std::min(noise, p.profile_noise_factor * deviation.median());
  }
  return std::max(p.min_gradient, p.gradient_noise_factor * noise);
}

bool finite(const Eigen::Vector2d& p) { return std::isfinite(p.x()) && std::isfinite(p.y()); }

/// The bilinear samples fx + j n, j = 0 .. count-1, of a row inside the image: each one's byte
/// offset of its top-left pixel (stride `stride_f`) and its weights. Four at a time in vector
/// registers (GCC's and Clang's vector extension: SSE2 or NEON), the same single-precision
/// operations as one at a time, so the same values.
void sample_addresses(float fx, float fy, float nx, float ny, float stride_f, int count, int* __restrict off,
                      float* __restrict ax, float* __restrict ay) {
  int j = 0;
#if defined(__GNUC__)
  using F4 = float __attribute__((vector_size(16)));
  using I4 = int __attribute__((vector_size(16)));
  const F4 lanes = {0.0f, 1.0f, 2.0f, 3.0f};
  for (; j + 4 <= count; j += 4) {
    const F4 jf = lanes + static_cast<float>(j);
    const F4 x = fx + jf * nx, y = fy + jf * ny;
    const F4 xi = __builtin_convertvector(__builtin_convertvector(x, I4), F4);
    const F4 yi = __builtin_convertvector(__builtin_convertvector(y, I4), F4);
    const F4 wx = x - xi, wy = y - yi;
    const I4 o = __builtin_convertvector(yi * stride_f + xi, I4);
    std::memcpy(ax + j, &wx, sizeof wx);
    std::memcpy(ay + j, &wy, sizeof wy);
    std::memcpy(off + j, &o, sizeof o);
  }
#endif
  for (; j < count; ++j) {
    const float x = fx + static_cast<float>(j) * nx, y = fy + static_cast<float>(j) * ny;
    const float xi = static_cast<float>(static_cast<int>(x)), yi = static_cast<float>(static_cast<int>(y));
    ax[j] = x - xi;
    ay[j] = y - yi;
    off[j] = static_cast<int>(yi * stride_f + xi);
  }
}

/// Bilinear values of `count` samples from their offsets and weights (sample_addresses): four at
/// a time where the vector extension is available, the same single-precision operations.
void bilinear_blend(const std::uint8_t* data, int stride, const int* __restrict off, const float* __restrict ax,
                    const float* __restrict ay, int count, float* __restrict val) {
  int k = 0;
#if defined(__GNUC__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  using F4 = float __attribute__((vector_size(16)));
  using I4 = int __attribute__((vector_size(16)));
  // A pixel and its right neighbour in one 16-bit load (little-endian: the pixel in the low byte).
  const auto pair = [](const std::uint8_t* p) {
    std::uint16_t v;
    std::memcpy(&v, p, sizeof v);
    return static_cast<int>(v);
  };
  for (; k + 4 <= count; k += 4) {
    const std::uint8_t* a = data + off[k];
    const std::uint8_t* b = data + off[k + 1];
    const std::uint8_t* c = data + off[k + 2];
    const std::uint8_t* d = data + off[k + 3];
    const I4 t = {pair(a), pair(b), pair(c), pair(d)};
    const I4 u = {pair(a + stride), pair(b + stride), pair(c + stride), pair(d + stride)};
    const F4 p00 = __builtin_convertvector(t & 0xff, F4), p01 = __builtin_convertvector(t >> 8, F4);
    const F4 p10 = __builtin_convertvector(u & 0xff, F4), p11 = __builtin_convertvector(u >> 8, F4);
    F4 wx, wy;
    std::memcpy(&wx, ax + k, sizeof wx);
    std::memcpy(&wy, ay + k, sizeof wy);
    const F4 top = p00 + wx * (p01 - p00);
    const F4 bot = p10 + wx * (p11 - p10);
    const F4 v = top + wy * (bot - top);
    std::memcpy(val + k, &v, sizeof v);
  }
#endif
  for (; k < count; ++k) {
    const std::uint8_t* r0 = data + off[k];
    const std::uint8_t* r1 = r0 + stride;
    const float top = r0[0] + ax[k] * (static_cast<float>(r0[1]) - r0[0]);
    const float bot = r1[0] + ax[k] * (static_cast<float>(r1[1]) - r1[0]);
    val[k] = top + ay[k] * (bot - top);
  }
}

/// Bilinear sample without clamping (the arithmetic of ImageView::sample, in single precision:
/// positions below 2^14 keep 1e-3 px); the caller guarantees kInsideMargin <= x <= width - 1 -
/// kInsideMargin, likewise y.
inline float sample_inside(const image::ImageView& img, float x, float y) {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const float ax = x - static_cast<float>(x0), ay = y - static_cast<float>(y0);
  const std::uint8_t* r0 = img.data + static_cast<long>(y0) * img.stride + x0;
  const std::uint8_t* r1 = r0 + img.stride;
  const float top = r0[0] + ax * (static_cast<float>(r0[1]) - r0[0]);
  const float bot = r1[0] + ax * (static_cast<float>(r1[1]) - r1[0]);
  return top + ay * (bot - top);
}

/// Parameters made safe to use: sizes at least the minimum the algorithm needs, NaN replaced by
/// the default. The tracker keeps (and reports through params()) the sanitized copy.
LineTrackerParams sanitize(LineTrackerParams p) {
  const LineTrackerParams def;
  p.rows = std::clamp(p.rows, 3, 4096);
  p.half_width = std::clamp(p.half_width, 2, 1024);
  p.max_candidates_per_row = std::clamp(p.max_candidates_per_row, 1, 64);
  p.ransac_iterations = std::clamp(p.ransac_iterations, 1, 1 << 20);
  if (!(p.end_margin >= 0.0)) p.end_margin = def.end_margin;
  p.end_margin = std::min(p.end_margin, 0.45);
  if (!(p.min_gradient >= 0.0f)) p.min_gradient = def.min_gradient;
  if (!(p.min_relative_strength >= 0.0f) || !std::isfinite(p.min_relative_strength))
    p.min_relative_strength = def.min_relative_strength;
  if (!(p.gradient_noise_factor >= 0.0f) || !std::isfinite(p.gradient_noise_factor))
    p.gradient_noise_factor = def.gradient_noise_factor;
  if (!(p.profile_noise_factor >= 0.0f) || !std::isfinite(p.profile_noise_factor))
    p.profile_noise_factor = def.profile_noise_factor;
  p.ramp_min_width = std::max(p.ramp_min_width, 0);
  if (!(p.inlier_tolerance > 0.0)) p.inlier_tolerance = def.inlier_tolerance;
  if (!(p.min_inlier_ratio >= 0.0)) p.min_inlier_ratio = def.min_inlier_ratio;
  if (!(p.max_angle > 0.0)) p.max_angle = def.max_angle;
  p.max_angle = std::min(p.max_angle, 1.5);
  p.side_offset = std::clamp(p.side_offset, 1, 64);
  p.side_width = std::clamp(p.side_width, 1, 32);
  if (!(p.appearance_k > 0.0)) p.appearance_k = def.appearance_k;
  if (!(p.appearance_min_sigma >= 0.0f)) p.appearance_min_sigma = def.appearance_min_sigma;
  if (!(p.chroma_min_sigma >= 0.0f)) p.chroma_min_sigma = def.chroma_min_sigma;
  if (!(p.shadow_tolerance >= 0.0f)) p.shadow_tolerance = def.shadow_tolerance;
  if (!(p.learning_rate > 0.0)) p.learning_rate = def.learning_rate;
  p.learning_rate = std::min(p.learning_rate, 1.0);
  if (!(p.learn_min_inlier_ratio >= 0.0)) p.learn_min_inlier_ratio = def.learn_min_inlier_ratio;
  if (!(p.outside_distinct_k >= 0.0) || !std::isfinite(p.outside_distinct_k)) p.outside_distinct_k = def.outside_distinct_k;
  return p;
}

}  // namespace

LineTracker::LineTracker(const LineTrackerParams& params) : p_(sanitize(params)) {
  const auto rows = static_cast<std::size_t>(p_.rows);
  cols_ = 2 * p_.half_width + 1;
  patch_.assign(rows * static_cast<std::size_t>(cols_), 0.0f);
  grad_.assign(rows * static_cast<std::size_t>(cols_), 0.0f);
  row_valid_.assign(rows, 0);
  col_inside_.assign(rows * static_cast<std::size_t>(cols_), 0);
  sample_off_.assign(3 * static_cast<std::size_t>(cols_), 0);
  sample_ax_.assign(3 * static_cast<std::size_t>(cols_), 0.0f);
  sample_ay_.assign(3 * static_cast<std::size_t>(cols_), 0.0f);
  sample_val_.assign(3 * static_cast<std::size_t>(cols_), 0.0f);
  colour_row_.assign(3 * static_cast<std::size_t>(cols_), 0.0f);
  colour_grad_.assign(3 * rows * static_cast<std::size_t>(cols_), 0.0f);
  row_v_.assign(rows, 0.0);
  row_centre_.assign(rows, Eigen::Vector2d::Zero());
  edgels_.assign(rows * static_cast<std::size_t>(p_.max_candidates_per_row), Edgel{});
  row_count_.assign(rows, 0);
  pool_.assign(edgels_.size(), 0);
  pool_cum_.assign(edgels_.size(), 0.0f);
  inlier_idx_.assign(rows, 0);
  // A failed grey fit's inliers stay when the colour gradient is tried after it (they anchor the
  // colour fit's refit on grey objects, where the colour gradient is mostly chroma noise): room
  // for both, so that no frame allocates.
  last_inliers_.reserve(2 * rows);
}

std::uint32_t LineTracker::next_random() {
  // xorshift32 (Marsaglia): period 2^32 - 1 on non-zero states.
  rng_ ^= rng_ << 13;
  rng_ ^= rng_ >> 17;
  rng_ ^= rng_ << 5;
  return rng_;
}

int LineTracker::score_line(const LineFit& line, int sign, float* strength_sum) {
  // Perpendicular distance of (u, v) from u = u0 + s v is |u - u0 - s v| / sqrt(1 + s^2).
  const double tol = p_.inlier_tolerance * std::sqrt(1.0 + line.s * line.s);
  const int k_max = p_.max_candidates_per_row;
  int count = 0;
  float strength = 0.0f;
  for (int i = 0; i < p_.rows; ++i) {
    if (!row_valid_[i]) continue;
    const double u_line = line.u0 + line.s * row_v_[i];
    int best = -1;
    double best_dist = tol;
    for (int k = 0; k < row_count_[i]; ++k) {
      const int idx = i * k_max + k;
      const Edgel& e = edgels_[idx];
      if (e.sign != sign) continue;
      const double dist = std::abs(e.u - u_line);
      if (dist <= best_dist) {
        best_dist = dist;
        best = idx;
      }
    }
    if (best >= 0) {
      inlier_idx_[count++] = best;
      strength += edgels_[best].strength;
    }
  }
  if (strength_sum != nullptr) *strength_sum = strength;
  return count;
}

bool LineTracker::fit_inliers(int count, LineFit* out) const {
  // Least squares of u as a linear function of v (the line is near-parallel to the v axis).
  if (count < 2) return false;
  double sv = 0.0, su = 0.0;
  for (int k = 0; k < count; ++k) {
    const Edgel& e = edgels_[inlier_idx_[k]];
    sv += e.v;
    su += e.u;
  }
  const double mv = sv / count, mu = su / count;
  double svv = 0.0, svu = 0.0;
  for (int k = 0; k < count; ++k) {
    const Edgel& e = edgels_[inlier_idx_[k]];
    const double dv = e.v - mv;
    svv += dv * dv;
    svu += dv * (e.u - mu);
  }
  if (!(svv > 1e-9)) return false;
  out->s = svu / svv;
  out->u0 = mu - out->s * mv;
  return std::isfinite(out->s) && std::isfinite(out->u0);
}


bool LineTracker::grey_band(int row, int col, int side, float* grey) const {
  // Samples at side_offset .. side_offset + side_width - 1 columns from the peak, on `side`. Inside
  // the window the smoothed patch row is reused; beyond it (an edgel near the window's border)
  // the image is sampled with the same 3-line smoothing along the edge.
  const int sgn = side == 0 ? -1 : 1;
  const float* prow = &patch_[static_cast<std::size_t>(row) * cols_];
  const unsigned char* inside = &col_inside_[static_cast<std::size_t>(row) * cols_];
  const Eigen::Vector2d first = row_centre_[row] - static_cast<double>(p_.half_width) * n_;
  float sum = 0.0f;
  int n = 0;
  for (int t = 0; t < p_.side_width; ++t) {
    const int j = col + sgn * (p_.side_offset + t);
    if (j >= 0 && j < cols_) {
      if (inside[j]) {
        sum += prow[j];
        ++n;
      }
      continue;
    }
    const Eigen::Vector2d q = first + static_cast<double>(j) * n_;
    const Eigen::Vector2d q0 = q - d_, q2 = q + d_;
    if (!img_.contains(q0.x(), q0.y(), kInsideMargin) || !img_.contains(q2.x(), q2.y(), kInsideMargin)) continue;
    sum += (sample_inside(img_, static_cast<float>(q0.x()), static_cast<float>(q0.y())) +
            sample_inside(img_, static_cast<float>(q.x()), static_cast<float>(q.y())) +
            sample_inside(img_, static_cast<float>(q2.x()), static_cast<float>(q2.y()))) *
           (1.0f / 3.0f);
    ++n;
  }
  if (n == 0) return false;
  *grey = sum / static_cast<float>(n);
  return true;
}

bool LineTracker::chroma_band(int row, int col, int side, float rg[2]) const {
  if (colour_ == nullptr) return false;
  const int sgn = side == 0 ? -1 : 1;
  const Eigen::Vector2d first = row_centre_[row] - static_cast<double>(p_.half_width) * n_;
  float bgr_sum[3] = {0.0f, 0.0f, 0.0f};
  int n = 0;
  for (int t = 0; t < p_.side_width; ++t) {
    const Eigen::Vector2d q = first + static_cast<double>(col + sgn * (p_.side_offset + t)) * n_;
    if (!colour_->contains(q.x(), q.y(), kInsideMargin)) continue;
    float bgr[3];
    colour_->sample_inside(q.x(), q.y(), bgr);
    bgr_sum[0] += bgr[0];
    bgr_sum[1] += bgr[1];
    bgr_sum[2] += bgr[2];
    ++n;
  }
  const float total = bgr_sum[0] + bgr_sum[1] + bgr_sum[2];
  if (n == 0 || !(total >= kMinChromaSum * static_cast<float>(n))) return false;
  rg[0] = bgr_sum[2] / total;  // r = R / (R + G + B)
  rg[1] = bgr_sum[1] / total;  // g = G / (R + G + B)
  return true;
}

bool LineTracker::appearance_ok(int row, int col) const {
  // Every learned object side must match; a side whose band leaves the image gives no evidence.
  for (int s = 0; s < 2; ++s) {
    const SideCheck& c = check_[s];
    if (!c.active) continue;
    float grey = 0.0f;
    const bool has_grey = grey_band(row, col, s, &grey);
    if (has_grey && !chroma_only_ && std::abs(grey - c.mean[0]) > c.tol[0]) return false;
    if (!c.chroma) continue;
    float rg[2];
    if (!chroma_band(row, col, s, rg)) continue;
    // Chromaticity noise grows as the light dims: widen its tolerance on a darkened band.
    float scale = 1.0f;
    if (has_grey && grey < c.mean[0]) scale = std::min(kMaxDarkScale, c.mean[0] / std::max(grey, 1.0f));
    if (std::abs(rg[0] - c.mean[1]) > c.tol[1] * scale || std::abs(rg[1] - c.mean[2]) > c.tol[2] * scale)
      return false;
  }
  // A silhouette candidate with the object's own colour outside it is a texture line inside.
  if (outside_check_.active) {
    const OutsideCheck& o = outside_check_;
    float rg[2];
    if (chroma_band(row, col, o.side, rg) && std::abs(rg[0] - o.mean[0]) <= o.tol[0] &&
        std::abs(rg[1] - o.mean[1]) <= o.tol[1])
      return false;
  }
  return true;
}

void LineTracker::prepare_outside_check(const LineTrackState& state) {
  outside_check_ = OutsideCheck{};
  if (!(p_.outside_distinct_k > 0.0) || colour_ == nullptr || state.outside_side < 0) return;
  const SideCheck& obj = check_[1 - state.outside_side];
  const SideAppearance& out = state.outside;
  if (!obj.active || !obj.chroma || !out.learned || out.channels != 3) return;
  if (!std::isfinite(out.mean[1]) || !std::isfinite(out.mean[2])) return;
  // Active only where the outside's learned colour stood apart from the object side's.
  const double k = p_.outside_distinct_k;
  const bool distinct =
      std::abs(out.mean[1] - obj.mean[1]) >= k * obj.tol[1] || std::abs(out.mean[2] - obj.mean[2]) >= k * obj.tol[2];
  if (!distinct) return;
  outside_check_.active = true;
  outside_check_.side = state.outside_side;
  for (int c = 0; c < 2; ++c) {
    outside_check_.mean[c] = obj.mean[c + 1];
    outside_check_.tol[c] = obj.tol[c + 1];
  }
}

void LineTracker::learn_sides(LineTrackState& state, const LineMeasurement& m, bool reset) const {
  for (int s = 0; s < 2; ++s)
    if (state.side[s].is_object) learn_band(state.side[s], s, m, reset);
  // A silhouette edge's other side (outside_distinct_k): learned alongside.
  if (p_.outside_distinct_k > 0.0 && state.outside_side >= 0) learn_band(state.outside, state.outside_side, m, reset);
}

void LineTracker::learn_band(SideAppearance& a, int s, const LineMeasurement& m, bool reset) const {
  const int count = m.inliers;
  // Band means of the inliers: frame mean and variance per channel.
  double sum[3] = {0.0, 0.0, 0.0}, sq[3] = {0.0, 0.0, 0.0};
  int n_grey = 0, n_chroma = 0;
  for (int k = 0; k < count; ++k) {
    const Edgel& e = edgels_[inlier_idx_[k]];
    float grey = 0.0f;
    if (!grey_band(e.row, e.col, s, &grey)) continue;
    sum[0] += grey;
    sq[0] += static_cast<double>(grey) * grey;
    ++n_grey;
    float rg[2];
    if (!chroma_band(e.row, e.col, s, rg)) continue;
    for (int c = 0; c < 2; ++c) {
      sum[c + 1] += rg[c];
      sq[c + 1] += static_cast<double>(rg[c]) * rg[c];
    }
    ++n_chroma;
  }
  if (n_grey < kMinInliers) return;
  const int channels = n_chroma >= kMinInliers ? 3 : 1;
  float mean[3] = {0.0f, 0.0f, 0.0f}, var[3] = {0.0f, 0.0f, 0.0f};
  for (int c = 0; c < channels; ++c) {
    const int n = c == 0 ? n_grey : n_chroma;
    const double mu = sum[c] / n;
    mean[c] = static_cast<float>(mu);
    var[c] = static_cast<float>(std::max(0.0, sq[c] / n - mu * mu));
  }
  if (reset || !a.learned) {
    // Learned from scratch only from a convincing fit.
    if (m.inlier_ratio < p_.learn_min_inlier_ratio) return;
    a.learned = true;
    a.channels = channels;
    for (int c = 0; c < 3; ++c) {
      a.mean[c] = mean[c];
      a.var[c] = var[c];
    }
    return;
  }
  // Running mean and variance: the mixture of the old estimate (weight 1 - r) and this frame's
  // (weight r), var = (1 - r) var_old + r var_frame + r (1 - r) (mean_frame - mean_old)^2.
  // A frame without colour updates the grey level and keeps the chromaticity; the first frame
  // with colour of a grey-learned side adds it.
  const float r = static_cast<float>(p_.learning_rate);
  const int blend = std::min(channels, a.channels == 3 ? 3 : 1);
  for (int c = 0; c < blend; ++c) {
    const float delta = mean[c] - a.mean[c];
    a.mean[c] += r * delta;
    a.var[c] = (1.0f - r) * a.var[c] + r * var[c] + r * (1.0f - r) * delta * delta;
  }
  if (channels == 3 && a.channels != 3) {
    a.channels = 3;
    for (int c = 1; c < 3; ++c) {
      a.mean[c] = mean[c];
      a.var[c] = var[c];
    }
  }
}

int LineTracker::extract_edgels(int want, bool cues, int* rejected) {
  // Edgels: local maxima of sign * g, the k_max strongest kept. Columns 2..cols-3 only, so that a
  // peak is a verified maximum; its support (columns j-2..j+2) must be inside the image. With
  // cues, a candidate strong enough to enter the row's slots must also pass the appearance check
  // (checked before it takes a slot, so that background edges cannot crowd out the object's).
  const int cols = cols_, w = p_.half_width, k_max = p_.max_candidates_per_row;
  int pool_size = 0;
  int n_rejected = 0;
  for (int i = 0; i < p_.rows; ++i) {
    row_count_[i] = 0;
    if (!row_valid_[i]) continue;
    const float* g = &grad_[static_cast<std::size_t>(i) * cols];
    const unsigned char* inside = &col_inside_[static_cast<std::size_t>(i) * cols];
    Edgel* slots = &edgels_[static_cast<std::size_t>(i) * k_max];
    int count = 0;
    int inside_run = 0;  // consecutive inside columns ending at j + 2
    for (int j = 0; j < 4 && j < cols; ++j) inside_run = inside[j] ? inside_run + 1 : 0;
    for (int j = 2; j < cols - 2; ++j) {
      inside_run = inside[j + 2] ? inside_run + 1 : 0;
      if (inside_run < 5 || j < col_lo_ || j > col_hi_) continue;
      const float gj = g[j];
      const int sign = gj > 0.0f ? 1 : -1;
      const float sg = sign * gj;
      if (!(sg >= thr_) || sg <= 0.0f) continue;
      if (want != 0 && sign != want) continue;
      const float left = sign * g[j - 1], right = sign * g[j + 1];
      if (!(sg >= left && sg > right)) continue;
      // Keep the k_max strongest, sorted by decreasing strength.
      int pos;
      if (count < k_max) {
        pos = count;
      } else if (sg > slots[k_max - 1].strength) {
        pos = k_max - 1;
      } else {
        continue;
      }
      // Sub-pixel peak: vertex of the parabola through the three values; on a blurred edge's
      // plateau (a run of at least ramp_min_width edge pixels of this sign at half the peak or
      // more, within the search range: a neighbouring edge's half is not ours), where the noise decides
      // which column peaks, the centroid of the run, kept once (for its strongest column; equal
      // ones: the leftmost).
      const float denom = left - 2.0f * sg + right;
      float delta = denom < -1e-6f ? 0.5f * (left - right) / denom : 0.0f;
      delta = std::clamp(delta, -0.5f, 0.5f);
      if (p_.ramp_min_width > 0) {
        const float half = std::max(0.5f * sg, thr_);
        int lo = j, hi = j;
        bool beaten = false;
        while (lo > col_lo_ && inside[lo - 1] && sign * g[lo - 1] >= half) {
          --lo;
          beaten = beaten || sign * g[lo] > sg;
        }
        while (hi < col_hi_ && inside[hi + 1] && sign * g[hi + 1] >= half) {
          ++hi;
          beaten = beaten || sign * g[hi] >= sg;
        }
        if (hi - lo + 1 >= p_.ramp_min_width) {
          if (beaten) continue;
          float sum = 0.0f, moment = 0.0f;
          for (int k = lo; k <= hi; ++k) {
            sum += sign * g[k];
            moment += sign * g[k] * static_cast<float>(k - j);
          }
          delta = moment / sum;
        }
      }
      if (cues && !appearance_ok(i, j)) {
        ++n_rejected;
        continue;
      }
      if (count < k_max) ++count;
      const Edgel e{static_cast<float>(j - w) + delta, static_cast<float>(row_v_[i]), sg, sign, i, j};
      while (pos > 0 && slots[pos - 1].strength < sg) {
        slots[pos] = slots[pos - 1];
        --pos;
      }
      slots[pos] = e;
    }
    // A pair followed as one: the strongest edgel of each sign (the slots are sorted by
    // strength), close enough and of comparable strength, make one at their midpoint; its sign
    // tells the order across the window (+1: the positive edge first, a bright bar on this row).
    bool paired = false;
    if (pair_span_ > 0.0f && count >= 2) {
      int kp = -1, kn = -1;
      for (int k = 0; k < count; ++k) {
        if (slots[k].sign > 0 && kp < 0) kp = k;
        if (slots[k].sign < 0 && kn < 0) kn = k;
      }
      if (kp >= 0 && kn >= 0 && std::abs(slots[kp].u - slots[kn].u) <= pair_span_ &&
          std::min(slots[kp].strength, slots[kn].strength) >= p_.pair_min_ratio * std::max(slots[kp].strength, slots[kn].strength)) {
        const Edgel& a = slots[kp];
        const Edgel& b = slots[kn];
        const int col = (a.col + b.col) / 2;
        slots[0] = Edgel{0.5f * (a.u + b.u), a.v, std::min(a.strength, b.strength), a.u < b.u ? 1 : -1, i, col};
        count = 1;
        paired = true;
      }
    }
    if (pairs_only_ && !paired) count = 0;
    row_count_[i] = count;
    for (int k = 0; k < count; ++k) {
      pool_[pool_size] = i * k_max + k;
      pool_cum_[pool_size] = (pool_size > 0 ? pool_cum_[pool_size - 1] : 0.0f) + slots[k].strength;
      ++pool_size;
    }
  }
  if (rejected != nullptr) *rejected = n_rejected;
  return pool_size;
}

void LineTracker::fit_pool(int pool_size, int valid_rows, LineMeasurement& m) {
  if (pool_size < kMinInliers) return;
  const int rows = p_.rows;

  // 4. RANSAC over pairs of edgels in different rows with the same sign; inliers must have that
  // sign too (an edge has one polarity: clutter edgels of the other sign cannot prop up a wrong
  // line). Where the polarity flips along a contour, the majority part is fitted.
  rng_ = p_.seed != 0 ? p_.seed : kDefaultSeed;
  const double tan_max = std::tan(p_.max_angle);
  int best_count = 0;
  float best_strength = -1.0f;
  LineFit best_line;
  int best_sign = 0;
  auto consider = [&](int ia, int ib) {
    const Edgel& e1 = edgels_[ia];
    const Edgel& e2 = edgels_[ib];
    if (e1.row == e2.row || e1.sign != e2.sign) return;
    LineFit line;
    line.s = static_cast<double>(e2.u - e1.u) / static_cast<double>(e2.v - e1.v);
    if (!(std::abs(line.s) <= tan_max)) return;
    line.u0 = e1.u - line.s * e1.v;
    float strength = 0.0f;
    const int count = score_line(line, e1.sign, &strength);
    if (count > best_count || (count == best_count && strength > best_strength)) {
      best_count = count;
      best_strength = strength;
      best_line = line;
      best_sign = e1.sign;
    }
  };
  const long pairs = static_cast<long>(pool_size) * (pool_size - 1) / 2;
  if (pairs <= p_.ransac_iterations) {
    // Few edgels: every pair is cheaper than sampling and cannot miss.
    for (int a = 0; a < pool_size; ++a)
      for (int b = a + 1; b < pool_size; ++b) consider(pool_[a], pool_[b]);
  } else {
    // Edgels are drawn with probability proportional to their gradient strength (the object
    // edge is usually the strongest maximum of most rows; clutter rows hold several weaker ones).
    const float total = pool_cum_[pool_size - 1];
    auto draw = [&]() {
      const float r = static_cast<float>(next_random() >> 8) * (1.0f / 16777216.0f) * total;
      const int k = static_cast<int>(std::upper_bound(pool_cum_.begin(), pool_cum_.begin() + pool_size, r) -
                                     pool_cum_.begin());
      return pool_[std::min(k, pool_size - 1)];
    };
    const double log_miss = std::log(1.0 - kRansacConfidence);
    int needed = p_.ransac_iterations;
    for (int it = 0; it < needed; ++it) {
      const int ia = draw();
      int ib = draw();
      // A few redraws for a partner in another row with the same sign; a failed draw still
      // counts as an iteration, which bounds the cost.
      for (int r = 0; r < 4 && (edgels_[ib].row == edgels_[ia].row || edgels_[ib].sign != edgels_[ia].sign);
           ++r)
        ib = draw();
      const int before = best_count;
      consider(ia, ib);
      if (best_count > before) {  // adaptive stop: iterations for an inlier pair at this inlier ratio
        const double w = static_cast<double>(best_count) / pool_size;
        const double miss = 1.0 - w * w;
        const double n = miss <= 1e-12 ? 1.0 : std::ceil(log_miss / std::log(miss));
        needed = static_cast<int>(std::min<double>(p_.ransac_iterations, std::max(n, 1.0)));
      }
    }
  }
  if (best_count < 2) return;

  // Refinement: least squares on the inliers, inliers recomputed once, final least squares.
  int count = score_line(best_line, best_sign, nullptr);
  LineFit fit;
  if (!fit_inliers(count, &fit)) return;
  float strength = 0.0f;
  count = score_line(fit, best_sign, &strength);
  // Inliers much weaker than the line's mean strength are noise that happens to lie on it (a
  // row where the edge is occluded): left out.
  const float min_strength = p_.min_relative_strength * strength / static_cast<float>(std::max(count, 1));
  int kept = 0;
  for (int k = 0; k < count; ++k)
    if (edgels_[inlier_idx_[k]].strength >= min_strength) inlier_idx_[kept++] = inlier_idx_[k];
  count = kept;
  LineFit final_fit;
  if (!fit_inliers(count, &final_fit)) return;

  // 5. Measurement in image coordinates.
  const double norm = std::sqrt(1.0 + final_fit.s * final_fit.s);
  double sq = 0.0;
  for (int k = 0; k < count; ++k) {
    const Edgel& e = edgels_[inlier_idx_[k]];
    const double dist = (e.u - final_fit.u0 - final_fit.s * e.v) / norm;
    sq += dist * dist;
    last_inliers_.push_back(row_centre_[e.row] + static_cast<double>(e.u) * n_);
  }
  const double u_first = final_fit.u0 + final_fit.s * row_v_[0];
  const double u_last = final_fit.u0 + final_fit.s * row_v_[rows - 1];
  m.line.a = row_centre_[0] + u_first * n_;
  m.line.b = row_centre_[rows - 1] + u_last * n_;
  m.offset_px = final_fit.u0;  // rows are centred on v = 0: mean u over the window
  m.inliers = count;
  m.inlier_ratio = static_cast<double>(count) / valid_rows;
  m.rms_px = std::sqrt(sq / count);
  m.polarity = best_sign;  // all inliers share it
  m.found = count >= kMinInliers && m.inlier_ratio >= p_.min_inlier_ratio && std::abs(final_fit.s) <= tan_max;
}

LineMeasurement LineTracker::track(const image::ImageView& img, const Segment2& predicted, LineTrackState& state,
                                   const image::ColourView* colour, SearchRange range) {
  LineMeasurement m;
  last_inliers_.clear();
  if (img.empty() || !finite(predicted.a) || !finite(predicted.b)) return m;
  const Eigen::Vector2d ab = predicted.b - predicted.a;
  const double len = ab.norm();
  if (!(len >= kMinSegmentLength) || !std::isfinite(len)) return m;

  // 1. Oriented window: rows along the edge, columns across it.
  const Eigen::Vector2d d = ab / len;
  const Eigen::Vector2d n(-d.y(), d.x());
  img_ = img;
  colour_ = (colour != nullptr && !colour->empty() && colour->width == img.width &&
             colour->height == img.height && colour->stride >= image::ColourView::kChannels * colour->width)
                ? colour
                : nullptr;
  d_ = d;
  n_ = n;
  const int rows = p_.rows, w = p_.half_width, cols = cols_;
  // Columns of the search range (offset = column - w), within 2..cols-3 (peaks need neighbours).
  col_lo_ = 2;
  col_hi_ = cols - 3;
  if (std::isfinite(range.lo) && range.lo > -w) col_lo_ = std::max(col_lo_, static_cast<int>(std::ceil(range.lo)) + w);
  if (std::isfinite(range.hi) && range.hi < w) col_hi_ = std::min(col_hi_, static_cast<int>(std::floor(range.hi)) + w);
  if (col_hi_ < col_lo_) return m;
  const double margin = p_.end_margin * len;
  const double step = (len - 2.0 * margin) / (rows - 1);  // pixels between rows (subsampling)
  const double mid = 0.5 * (rows - 1);
  const Eigen::Vector2d start = predicted.a + margin * d;
  pair_span_ = range.pair_span > 0.0 ? static_cast<float>(range.pair_span) : 0.0f;
  const bool pair = pair_span_ > 0.0f;
  const int want = pair ? 0 : (state.polarity > 0 ? 1 : (state.polarity < 0 ? -1 : 0));
  int valid_rows = 0;
  for (int i = 0; i < rows; ++i) {
    const Eigen::Vector2d c = start + (i * step) * d;
    row_centre_[i] = c;
    row_v_[i] = (i - mid) * step;
    row_count_[i] = 0;
    const bool valid = img.contains(c.x(), c.y(), kRowMargin);
    row_valid_[i] = valid ? 1 : 0;
    if (!valid) continue;
    ++valid_rows;

    // Prewitt smoothing along the edge: the mean of the three image lines at -1, 0, +1 pixel along
    // d through the row centre, whatever the row spacing (rows of a long edge are far apart).
    // Columns whose samples leave the image are sampled clamped but marked, so that no edgel is
    // taken from the clamped border extension.
    float* prow = &patch_[static_cast<std::size_t>(i) * cols];
    unsigned char* inside = &col_inside_[static_cast<std::size_t>(i) * cols];
    const Eigen::Vector2d first = c - static_cast<double>(w) * n, last = c + static_cast<double>(w) * n;
    const bool row_inside = img.contains(first.x() - d.x(), first.y() - d.y(), kInsideMargin) &&
                            img.contains(first.x() + d.x(), first.y() + d.y(), kInsideMargin) &&
                            img.contains(last.x() - d.x(), last.y() - d.y(), kInsideMargin) &&
                            img.contains(last.x() + d.x(), last.y() + d.y(), kInsideMargin);
    if (row_inside) {
      // Fast path: the four corners inside => every sample inside (the image is convex).
      // Two passes: sample addresses and weights (vectorisable: the offset is computed in single
      // precision, exact below 2^24), then the bilinear blends.
      const float nx = static_cast<float>(n.x()), ny = static_cast<float>(n.y());
      const float dx = static_cast<float>(d.x()), dy = static_cast<float>(d.y());
      const int stride = img.stride;
      const float stride_f = static_cast<float>(stride);
      int* __restrict off = sample_off_.data();
      float* __restrict ax = sample_ax_.data();
      float* __restrict ay = sample_ay_.data();
      float* __restrict val = sample_val_.data();
      for (int l = 0; l < 3; ++l) {
        const float fx = static_cast<float>(first.x()) + static_cast<float>(l - 1) * dx;
        const float fy = static_cast<float>(first.y()) + static_cast<float>(l - 1) * dy;
        const int base = l * cols;
        sample_addresses(fx, fy, nx, ny, stride_f, cols, off + base, ax + base, ay + base);
      }
      const std::uint8_t* data = img.data;
      bilinear_blend(data, stride, off, ax, ay, 3 * cols, val);
      for (int j = 0; j < cols; ++j) {
        prow[j] = (val[j] + val[cols + j] + val[2 * cols + j]) * (1.0f / 3.0f);
        inside[j] = 1;
      }
    } else {
      for (int j = 0; j < cols; ++j) {
        const Eigen::Vector2d q = first + static_cast<double>(j) * n;
        const double x0 = q.x() - d.x(), y0 = q.y() - d.y(), x2 = q.x() + d.x(), y2 = q.y() + d.y();
        const float acc = img.sample(x0, y0) + img.sample(q.x(), q.y()) + img.sample(x2, y2);
        prow[j] = acc * (1.0f / 3.0f);
        inside[j] = (img.contains(x0, y0) && img.contains(x2, y2)) ? 1 : 0;
      }
    }
  }
  if (valid_rows < kMinInliers) return m;
  grey_gradient();
  if (pair) {
    // The pair's centre: no cues, nothing learned; on a colour image, when the grey gradient
    // shows no pair, on the colour gradient (a plate between surfaces of its own brightness).
    detect(0, false, valid_rows, m, false);
    float axis[3];
    if (!m.found && colour_ != nullptr && p_.use_colour_gradient && colour_gradient(state, axis)) {
      m = LineMeasurement{};
      m.threshold = thr_;
      pairs_only_ = true;  // (single colour edges: mostly the chroma noise of grey faces)
      detect(0, false, valid_rows, m, false);
      pairs_only_ = false;
      m.colour_gradient = m.found;
    }
    return m;
  }

  // Appearance checks of the learned object sides (paper 4.1).
  bool cues = false;
  for (int s = 0; s < 2; ++s) {
    SideCheck& c = check_[s];
    const SideAppearance& a = state.side[s];
    c = SideCheck{};
    if (!p_.use_cues || !a.is_object || !a.learned) continue;
    const int channels = a.channels == 3 ? 3 : 1;
    bool sane = true;
    for (int ch = 0; ch < channels; ++ch) sane = sane && std::isfinite(a.mean[ch]) && std::isfinite(a.var[ch]);
    if (!sane) continue;
    const float k = static_cast<float>(p_.appearance_k);
    c.active = true;
    c.chroma = colour_ != nullptr && channels == 3;
    c.mean[0] = a.mean[0];
    c.tol[0] = k * std::max(std::sqrt(std::max(a.var[0], 0.0f)), p_.appearance_min_sigma);
    if (c.chroma) {
      // Chromaticity carries the identity of the face; intensity may drop in a shadow.
      c.tol[0] = std::max(c.tol[0], p_.shadow_tolerance * a.mean[0]);
      for (int ch = 1; ch < 3; ++ch) {
        c.mean[ch] = a.mean[ch];
        c.tol[ch] = k * std::max(std::sqrt(std::max(a.var[ch], 0.0f)), p_.chroma_min_sigma);
      }
    }
    cues = true;
  }

  // A silhouette edge (one object side) learns its other side too; a change of which side that
  // is forgets what was learned.
  const int outside = state.side[0].is_object != state.side[1].is_object ? (state.side[0].is_object ? 1 : 0) : -1;
  if (outside != state.outside_side) {
    state.outside = SideAppearance{};
    state.outside_side = outside;
  }
  prepare_outside_check(state);

  // 3-5. Edgels, RANSAC, measurement on the grey gradient; on a colour image, when that finds
  // no edge, again on the colour gradient (an edge between surfaces of equal brightness). The
  // cues come first: a search whose learned cues leave no edge is repeated without them (a
  // fallback). With colour_before_fallback, both gradients are searched with the cues before
  // either is searched without.
  m.threshold = thr_;
  const bool colour_search = colour_ != nullptr && p_.use_colour_gradient;
  // The colour gradient's search; true (and m set, the state updated) when it finds the edge.
  auto colour_pass = [&](bool with_cues, bool allow_fallback, bool after_fallback) {
    float axis[3];
    if (!colour_gradient(state, axis)) return false;
    LineMeasurement mc;
    mc.threshold = thr_;
    const int want_c = state.colour_polarity > 0 ? 1 : (state.colour_polarity < 0 ? -1 : 0);
    detect(want_c, with_cues, valid_rows, mc, allow_fallback);
    if (!mc.found) return false;
    mc.colour_gradient = true;
    if (after_fallback) {
      mc.cue_fallback = true;
      mc.cue_rejected = m.cue_rejected;
    }
    state.colour_polarity = mc.polarity;
    for (int c = 0; c < 3; ++c) state.colour_axis[c] = axis[c];
    m = mc;
    if (p_.use_cues) learn_sides(state, m, m.cue_fallback);
    return true;
  };
  if (cues && colour_search && p_.colour_before_fallback) {
    detect(want, true, valid_rows, m, false);
    if (!m.found) {
      if (colour_pass(true, false, false)) return m;
      // Neither gradient shows an edge that passes the cues: both again with the chromaticity
      // check only (fallback_keeps_chroma), or without any check.
      const bool keep_chroma = p_.fallback_keeps_chroma && (check_[0].chroma || check_[1].chroma);
      const int rejected = m.cue_rejected;
      for (int stage = keep_chroma ? 0 : 1; stage < 2 && !m.found; ++stage) {
        if (stage == 1 && keep_chroma && !p_.fallback_unchecked) break;
        grey_gradient();
        m = LineMeasurement{};
        m.threshold = thr_;
        chroma_only_ = stage == 0;
        detect(want, stage == 0, valid_rows, m, false);
        m.cue_fallback = true;
        m.cue_rejected = rejected;
        const bool found_colour = !m.found && colour_pass(stage == 0, false, true);
        chroma_only_ = false;
        if (found_colour) return m;
      }
    }
  } else {
    detect(want, cues, valid_rows, m, true);
    if (!m.found && colour_search && colour_pass(cues, true, false)) return m;
  }
  if (!m.found) return m;
  state.polarity = m.polarity;
  // The appearance of the object sides is learned from the inliers; after a fallback, from scratch.
  if (p_.use_cues) learn_sides(state, m, m.cue_fallback);
  return m;
}

void LineTracker::grey_gradient() {
  // Gradient across: central difference of the smoothed row (grey levels per pixel).
  const int cols = cols_;
  for (int i = 0; i < p_.rows; ++i) {
    if (!row_valid_[i]) continue;
    const float* prow = &patch_[static_cast<std::size_t>(i) * cols];
    float* g = &grad_[static_cast<std::size_t>(i) * cols];
    g[0] = 0.0f;
    g[cols - 1] = 0.0f;
    for (int j = 1; j < cols - 1; ++j) g[j] = 0.5f * (prow[j + 1] - prow[j - 1]);
  }
  thr_ = window_threshold(p_, grad_.data(), row_valid_.data(), col_inside_.data(), p_.rows, cols, colour_row_.data());
}

void LineTracker::detect(int want, bool cues, int valid_rows, LineMeasurement& m, bool allow_fallback) {
  // With cues, the candidates passing the check must still be able to make a found edge; else
  // (the light changed abruptly, the face is shadowed, ...) the edge is searched again without
  // the check (when allow_fallback), and the result says so.
  const float threshold = m.threshold;
  bool fallback = false;
  if (cues) {
    int rejected = 0;
    const int pool_size = extract_edgels(want, true, &rejected);
    m.cue_rejected = rejected;
    int rows_with = 0;
    for (int i = 0; i < p_.rows; ++i) rows_with += row_count_[i] > 0 ? 1 : 0;
    const int need = std::max(kMinInliers, static_cast<int>(std::ceil(p_.min_inlier_ratio * valid_rows)));
    if (rows_with >= need) fit_pool(pool_size, valid_rows, m);
    if (!m.found) last_inliers_.clear();
    if (!m.found && allow_fallback) {
      fallback = true;
      m = LineMeasurement{};
      m.cue_rejected = rejected;
      m.cue_fallback = true;
      m.threshold = threshold;
      last_inliers_.clear();
      // Colour: the light changes a face's brightness, hardly its chromaticity, which the
      // fallback keeps checking (fallback_keeps_chroma).
      if (p_.fallback_keeps_chroma && (check_[0].chroma || check_[1].chroma)) {
        chroma_only_ = true;
        fit_pool(extract_edgels(want, true, nullptr), valid_rows, m);
        chroma_only_ = false;
        if (m.found || !p_.fallback_unchecked) return;
        m = LineMeasurement{};
        m.cue_rejected = rejected;
        m.cue_fallback = true;
        m.threshold = threshold;
        last_inliers_.clear();
      }
    }
  }
  if (!cues || fallback) fit_pool(extract_edgels(want, false, nullptr), valid_rows, m);
}

bool LineTracker::colour_gradient(const LineTrackState& state, float axis[3]) {
  // Per row: B, G, R sampled like the grey patch (mean of the three lines at -1, 0, +1 pixel
  // along the edge), central differences across; the 3x3 scatter of the per-channel gradients
  // over the window gives the principal colour direction, on which the gradients are projected.
  const int rows = p_.rows, cols = cols_, w = p_.half_width;
  Eigen::Matrix3f S = Eigen::Matrix3f::Zero();
  for (int i = 0; i < rows; ++i) {
    if (!row_valid_[i]) continue;
    const Eigen::Vector2d first = row_centre_[i] - static_cast<double>(w) * n_;
    const unsigned char* inside = &col_inside_[static_cast<std::size_t>(i) * cols];
    for (int j = 0; j < cols; ++j) {
      float acc[3] = {0.0f, 0.0f, 0.0f};
      const Eigen::Vector2d q = first + static_cast<double>(j) * n_;
      for (int l = -1; l <= 1; ++l) {
        float bgr[3];
        colour_->sample(q.x() + l * d_.x(), q.y() + l * d_.y(), bgr);
        acc[0] += bgr[0];
        acc[1] += bgr[1];
        acc[2] += bgr[2];
      }
      for (int c = 0; c < 3; ++c) colour_row_[static_cast<std::size_t>(c) * cols + j] = acc[c] * (1.0f / 3.0f);
    }
    float* cg = &colour_grad_[static_cast<std::size_t>(i) * cols * 3];
    for (int j = 0; j < cols; ++j) {
      const bool in = j > 0 && j < cols - 1 && inside[j - 1] && inside[j + 1];
      Eigen::Vector3f gv = Eigen::Vector3f::Zero();
      if (in)
        for (int c = 0; c < 3; ++c)
          gv[c] = 0.5f * (colour_row_[static_cast<std::size_t>(c) * cols + j + 1] -
                          colour_row_[static_cast<std::size_t>(c) * cols + j - 1]);
      cg[3 * j] = gv[0];
      cg[3 * j + 1] = gv[1];
      cg[3 * j + 2] = gv[2];
      S.noalias() += gv * gv.transpose();
    }
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> es(S);
  if (es.info() != Eigen::Success || !(es.eigenvalues()[2] > 0.0f)) return false;
  Eigen::Vector3f e = es.eigenvectors().col(2);
  // Sign: along the last colour edge's direction when known, else towards brighter.
  const Eigen::Vector3f ref(state.colour_axis[0], state.colour_axis[1], state.colour_axis[2]);
  const float s = ref.squaredNorm() > 0.5f ? e.dot(ref) : e.sum();
  if (s < 0.0f) e = -e;
  for (int i = 0; i < rows; ++i) {
    float* g = &grad_[static_cast<std::size_t>(i) * cols];
    if (!row_valid_[i]) continue;
    const float* cg = &colour_grad_[static_cast<std::size_t>(i) * cols * 3];
    for (int j = 0; j < cols; ++j) g[j] = e[0] * cg[3 * j] + e[1] * cg[3 * j + 1] + e[2] * cg[3 * j + 2];
  }
  thr_ = window_threshold(p_, grad_.data(), row_valid_.data(), col_inside_.data(), rows, cols, colour_row_.data());
  for (int c = 0; c < 3; ++c) axis[c] = e[c];
  return true;
}

}  // namespace v4r::features
