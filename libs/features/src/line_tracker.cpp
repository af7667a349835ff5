// v4r - robust model-based object tracking. MIT licence.
#include "v4r/features/line_tracker.hpp"

#include <algorithm>
#include <cmath>

namespace v4r::features {

namespace {

constexpr double kMinSegmentLength = 3.0;  // pixels: shorter predictions are degenerate
constexpr double kRowMargin = 1.0;         // pixels: a row centre must lie this far inside the image
constexpr int kMinInliers = 3;             // a line needs at least this many inlier rows
constexpr std::uint32_t kDefaultSeed = 0x9E3779B9u;  // xorshift state must not be zero

constexpr double kInsideMargin = 0.01;     // pixels: keeps x0 + 1, y0 + 1 of a bilinear sample inside

bool finite(const Eigen::Vector2d& p) { return std::isfinite(p.x()) && std::isfinite(p.y()); }

/// Bilinear sample without clamping (same arithmetic as ImageView::sample); the caller guarantees
/// kInsideMargin <= x <= width - 1 - kInsideMargin, likewise y.
inline float sample_inside(const image::ImageView& img, double x, double y) {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const float ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
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
  if (!(p.inlier_tolerance > 0.0)) p.inlier_tolerance = def.inlier_tolerance;
  if (!(p.min_inlier_ratio >= 0.0)) p.min_inlier_ratio = def.min_inlier_ratio;
  if (!(p.max_angle > 0.0)) p.max_angle = def.max_angle;
  p.max_angle = std::min(p.max_angle, 1.5);
  return p;
}

}  // namespace

LineTracker::LineTracker(const LineTrackerParams& params) : p_(sanitize(params)) {
  const auto rows = static_cast<std::size_t>(p_.rows);
  cols_ = 2 * p_.half_width + 1;
  patch_.assign(rows * static_cast<std::size_t>(cols_), 0.0f);
  grad_.assign(rows * static_cast<std::size_t>(cols_), 0.0f);
  row_valid_.assign(rows, 0);
  col_inside_.assign(static_cast<std::size_t>(cols_), 0);
  row_v_.assign(rows, 0.0);
  row_centre_.assign(rows, Eigen::Vector2d::Zero());
  edgels_.assign(rows * static_cast<std::size_t>(p_.max_candidates_per_row), Edgel{});
  row_count_.assign(rows, 0);
  pool_.assign(edgels_.size(), 0);
  pool_cum_.assign(edgels_.size(), 0.0f);
  inlier_idx_.assign(rows, 0);
  last_inliers_.reserve(rows);
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

LineMeasurement LineTracker::track(const image::ImageView& img, const Segment2& predicted,
                                   LineTrackState& state) {
  LineMeasurement m;
  last_inliers_.clear();
  if (img.empty() || !finite(predicted.a) || !finite(predicted.b)) return m;
  const Eigen::Vector2d ab = predicted.b - predicted.a;
  const double len = ab.norm();
  if (!(len >= kMinSegmentLength) || !std::isfinite(len)) return m;

  // 1. Oriented window: rows along the edge, columns across it.
  const Eigen::Vector2d d = ab / len;
  const Eigen::Vector2d n(-d.y(), d.x());
  const int rows = p_.rows, w = p_.half_width, cols = cols_;
  const double margin = p_.end_margin * len;
  const double step = (len - 2.0 * margin) / (rows - 1);  // pixels between rows (subsampling)
  const double mid = 0.5 * (rows - 1);
  const Eigen::Vector2d start = predicted.a + margin * d;
  const int k_max = p_.max_candidates_per_row;
  const int want = state.polarity > 0 ? 1 : (state.polarity < 0 ? -1 : 0);
  int valid_rows = 0;
  int pool_size = 0;
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
    const Eigen::Vector2d first = c - static_cast<double>(w) * n, last = c + static_cast<double>(w) * n;
    const bool row_inside = img.contains(first.x() - d.x(), first.y() - d.y(), kInsideMargin) &&
                            img.contains(first.x() + d.x(), first.y() + d.y(), kInsideMargin) &&
                            img.contains(last.x() - d.x(), last.y() - d.y(), kInsideMargin) &&
                            img.contains(last.x() + d.x(), last.y() + d.y(), kInsideMargin);
    if (row_inside) {
      // Fast path: the four corners inside => every sample inside (the image is convex).
      for (int j = 0; j < cols; ++j) {
        const Eigen::Vector2d q = first + static_cast<double>(j) * n;
        const float acc = sample_inside(img, q.x() - d.x(), q.y() - d.y()) + sample_inside(img, q.x(), q.y()) +
                          sample_inside(img, q.x() + d.x(), q.y() + d.y());
        prow[j] = acc * (1.0f / 3.0f);
        col_inside_[j] = 1;
      }
    } else {
      for (int j = 0; j < cols; ++j) {
        const Eigen::Vector2d q = first + static_cast<double>(j) * n;
        const double x0 = q.x() - d.x(), y0 = q.y() - d.y(), x2 = q.x() + d.x(), y2 = q.y() + d.y();
        const float acc = img.sample(x0, y0) + img.sample(q.x(), q.y()) + img.sample(x2, y2);
        prow[j] = acc * (1.0f / 3.0f);
        col_inside_[j] = (img.contains(x0, y0) && img.contains(x2, y2)) ? 1 : 0;
      }
    }

    // 2. Gradient across: central difference of the smoothed row (grey levels per pixel).
    float* g = &grad_[static_cast<std::size_t>(i) * cols];
    g[0] = 0.0f;
    g[cols - 1] = 0.0f;
    for (int j = 1; j < cols - 1; ++j) g[j] = 0.5f * (prow[j + 1] - prow[j - 1]);

    // 3. Edgels: local maxima of sign * g, the k_max strongest kept. Columns 2..cols-3 only, so
    // that a peak is a verified maximum; its support (columns j-2..j+2) must be inside the image.
    Edgel* slots = &edgels_[static_cast<std::size_t>(i) * k_max];
    int count = 0;
    int inside_run = 0;  // consecutive inside columns ending at j + 2
    for (int j = 0; j < 4 && j < cols; ++j) inside_run = col_inside_[j] ? inside_run + 1 : 0;
    for (int j = 2; j < cols - 2; ++j) {
      inside_run = col_inside_[j + 2] ? inside_run + 1 : 0;
      if (inside_run < 5) continue;
      const float gj = g[j];
      const int sign = gj > 0.0f ? 1 : -1;
      const float sg = sign * gj;
      if (!(sg >= p_.min_gradient) || sg <= 0.0f) continue;
      if (want != 0 && sign != want) continue;
      const float left = sign * g[j - 1], right = sign * g[j + 1];
      if (!(sg >= left && sg > right)) continue;
      // Sub-pixel peak: vertex of the parabola through the three values.
      const float denom = left - 2.0f * sg + right;
      float delta = denom < -1e-6f ? 0.5f * (left - right) / denom : 0.0f;
      delta = std::clamp(delta, -0.5f, 0.5f);
      const Edgel e{static_cast<float>(j - w) + delta, static_cast<float>(row_v_[i]), sg, sign, i};
      // Keep the k_max strongest, sorted by decreasing strength.
      int pos;
      if (count < k_max) {
        pos = count++;
      } else if (sg > slots[k_max - 1].strength) {
        pos = k_max - 1;
      } else {
        continue;
      }
      while (pos > 0 && slots[pos - 1].strength < sg) {
        slots[pos] = slots[pos - 1];
        --pos;
      }
      slots[pos] = e;
    }
    row_count_[i] = count;
    for (int k = 0; k < count; ++k) {
      pool_[pool_size] = i * k_max + k;
      pool_cum_[pool_size] = (pool_size > 0 ? pool_cum_[pool_size - 1] : 0.0f) + slots[k].strength;
      ++pool_size;
    }
  }
  if (valid_rows < kMinInliers) return m;
  if (pool_size < kMinInliers) return m;

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
    for (int it = 0; it < p_.ransac_iterations; ++it) {
      const int ia = draw();
      int ib = draw();
      // A few redraws for a partner in another row with the same sign; a failed draw still
      // counts as an iteration, which bounds the cost.
      for (int r = 0; r < 4 && (edgels_[ib].row == edgels_[ia].row || edgels_[ib].sign != edgels_[ia].sign);
           ++r)
        ib = draw();
      consider(ia, ib);
    }
  }
  if (best_count < 2) return m;

  // Refinement: least squares on the inliers, inliers recomputed once, final least squares.
  int count = score_line(best_line, best_sign, nullptr);
  LineFit fit;
  if (!fit_inliers(count, &fit)) return m;
  count = score_line(fit, best_sign, nullptr);
  LineFit final_fit;
  if (!fit_inliers(count, &final_fit)) return m;

  // 5. Measurement in image coordinates.
  const double norm = std::sqrt(1.0 + final_fit.s * final_fit.s);
  double sq = 0.0;
  for (int k = 0; k < count; ++k) {
    const Edgel& e = edgels_[inlier_idx_[k]];
    const double dist = (e.u - final_fit.u0 - final_fit.s * e.v) / norm;
    sq += dist * dist;
    last_inliers_.push_back(row_centre_[e.row] + static_cast<double>(e.u) * n);
  }
  const double u_first = final_fit.u0 + final_fit.s * row_v_[0];
  const double u_last = final_fit.u0 + final_fit.s * row_v_[rows - 1];
  m.line.a = row_centre_[0] + u_first * n;
  m.line.b = row_centre_[rows - 1] + u_last * n;
  m.offset_px = final_fit.u0;  // rows are centred on v = 0: mean u over the window
  m.inliers = count;
  m.inlier_ratio = static_cast<double>(count) / valid_rows;
  m.rms_px = std::sqrt(sq / count);
  m.polarity = best_sign;  // all inliers share it
  m.found = count >= kMinInliers && m.inlier_ratio >= p_.min_inlier_ratio &&
            std::abs(final_fit.s) <= tan_max;
  if (m.found) state.polarity = m.polarity;
  return m;
}

}  // namespace v4r::features
