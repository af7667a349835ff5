// v4r - robust model-based object tracking. MIT licence.
#include "v4r/features/ellipse_tracker.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

namespace v4r::features {

namespace {

using Matrix5d = Eigen::Matrix<double, 5, 5>;
using Vector5d = Eigen::Matrix<double, 5, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

constexpr int kMinSamples = 6;                 // fewer samples cannot give 6 inliers
constexpr int kMinInliers = 6;                 // a found ellipse needs at least this many inlier lines
constexpr int kHypothesisSize = 5;             // edge points per RANSAC hypothesis
constexpr int kHypothesisIterations = 3;       // Gauss-Newton iterations of a hypothesis
constexpr int kRefineIterations = 5;           // Gauss-Newton iterations of a refinement on inliers
constexpr int kRefineRounds = 4;               // refit / re-score rounds after RANSAC
constexpr int kRedraws = 8;                    // redraws for a partner on a new line with the same sign
constexpr double kMaxCentreShiftFactor = 2.0;  // gate: centre moves at most this times half_length
constexpr double kMaxAxisChange = 0.3;         // gate: relative change of each semi-axis
constexpr double kShapePriorFraction = 0.15;   // prior sigma of the shape, fraction of the size
constexpr double kFinalSigmas = 3.5;          // final inlier gate, robust standard deviations
constexpr double kMinFinalToleranceFraction = 0.4;  // ... but at least this fraction of inlier_tolerance
constexpr double kCosMaxInlierAngle = 0.94;    // inlier: gradient within ~20 degrees of the fitted normal
constexpr double kInnerCurvatureFraction = 0.7;  // inner search range <= this x radius of curvature
constexpr double kMinEdgeSigmaPx = 0.05;       // floor of the edge noise estimate (pixels)
constexpr double kMadToSigma = 1.4826;         // median absolute residual -> Gaussian sigma
constexpr double kRansacConfidence = 0.99;     // adaptive stop: probability of an all-inlier draw
constexpr double kMinAxisPx = 1.0;             // predicted ellipses thinner than this are degenerate
constexpr double kMaxAxisPx = 1e5;             // ... and larger than this
constexpr double kMaxPredictionRmsFactor = 0.5;  // samples' RMS distance to their conic <= this * L
constexpr double kLineMargin = 1.0;            // pixels: a sample point must be this far inside the image
constexpr double kInsideMargin = 0.01;         // pixels: keeps x0 + 1, y0 + 1 of a bilinear sample inside
constexpr std::uint32_t kDefaultSeed = 0x9E3779B9u;  // xorshift state must not be zero

bool finite(const Eigen::Vector2d& p) { return std::isfinite(p.x()) && std::isfinite(p.y()); }

/// Parameters made safe to use: sizes clamped to what the algorithm needs, NaN replaced by the
/// default. The tracker keeps (and reports through params()) the sanitised copy.
EllipseTrackerParams sanitize(EllipseTrackerParams p) {
  const EllipseTrackerParams def;
  p.max_samples = std::clamp(p.max_samples, kMinSamples, 4096);
  p.half_length = std::clamp(p.half_length, 1, 1024);
  p.max_candidates_per_line = std::clamp(p.max_candidates_per_line, 1, 16);
  p.ransac_iterations = std::clamp(p.ransac_iterations, 1, 1 << 20);
  if (!(p.min_gradient >= 0.0f) || !std::isfinite(p.min_gradient)) p.min_gradient = def.min_gradient;
  if (!(p.inlier_tolerance > 0.0) || !std::isfinite(p.inlier_tolerance)) p.inlier_tolerance = def.inlier_tolerance;
  if (!(p.min_inlier_ratio >= 0.0) || !std::isfinite(p.min_inlier_ratio)) p.min_inlier_ratio = def.min_inlier_ratio;
  if (!(p.max_edge_angle > 0.0) || !std::isfinite(p.max_edge_angle)) p.max_edge_angle = def.max_edge_angle;
  p.max_edge_angle = std::min(p.max_edge_angle, 1.5);
  return p;
}

/// Semi-axes a >= b and angle of the a-axis of {x : x^T S x = 1}, S symmetric 2x2 (any units).
/// False unless S is positive definite.
bool shape_axes(double s11, double s12, double s22, double* a, double* b, double* angle) {
  const double tr = s11 + s22;
  const double det = s11 * s22 - s12 * s12;
  if (!(s11 > 0.0) || !(s22 > 0.0) || !(det > 0.0) || !std::isfinite(tr) || !std::isfinite(det)) return false;
  const double half_diff = 0.5 * (s11 - s22);
  const double root = std::sqrt(half_diff * half_diff + s12 * s12);
  const double l_small = 0.5 * tr - root, l_big = 0.5 * tr + root;  // eigenvalues, l_small > 0 as det > 0
  if (!(l_small > 0.0)) return false;
  *a = 1.0 / std::sqrt(l_small);
  *b = 1.0 / std::sqrt(l_big);
  // Eigenvector of l_small: the a-axis. 2 * angle = atan2(-2 s12, -(s11 - s22)).
  *angle = 0.5 * std::atan2(-2.0 * s12, -(s11 - s22));
  return std::isfinite(*a) && std::isfinite(*b) && std::isfinite(*angle);
}

/// Sampson distance r = f / |grad f| of point q from the ellipse f(q) = (q - c)^T S (q - c) - 1 = 0,
/// and optionally its gradient with respect to v = (cx, cy, S11, S12, S22). False at the centre.
inline bool sampson(const Vector5d& v, const Eigen::Vector2d& q, double* r, Vector5d* jac) {
  const double u1 = q.x() - v[0], u2 = q.y() - v[1];
  const double s11 = v[2], s12 = v[3], s22 = v[4];
  const double v1 = s11 * u1 + s12 * u2, v2 = s12 * u1 + s22 * u2;  // S u = grad f / 2
  const double nv2 = v1 * v1 + v2 * v2;
  if (!(nv2 > 1e-24)) return false;
  const double nv = std::sqrt(nv2);
  const double f = u1 * v1 + u2 * v2 - 1.0;
  *r = f / (2.0 * nv);
  if (jac != nullptr) {
    // r = f / (2|v|): dr = df / (2|v|) - f d|v| / (2|v|^2), d|v| = v . dv / |v|.
    const double inv = 1.0 / (2.0 * nv);
    const double k = f / (2.0 * nv2 * nv);  // f / (2 |v|^3), multiplies v . dv
    // Centre: df/dc = -2 v, dv/dc = -S, so v . dv/dc = -(S v).
    const double sv1 = s11 * v1 + s12 * v2, sv2 = s12 * v1 + s22 * v2;
    (*jac)[0] = -2.0 * v1 * inv + k * sv1;
    (*jac)[1] = -2.0 * v2 * inv + k * sv2;
    // Shape: df/dS11 = u1^2, dv = (u1, 0); df/dS12 = 2 u1 u2, dv = (u2, u1); df/dS22 = u2^2, dv = (0, u2).
    (*jac)[2] = u1 * u1 * inv - k * v1 * u1;
    (*jac)[3] = 2.0 * u1 * u2 * inv - k * (v1 * u2 + v2 * u1);
    (*jac)[4] = u2 * u2 * inv - k * v2 * u2;
  }
  return std::isfinite(*r);
}

}  // namespace

Eigen::Matrix<double, 6, 1> Ellipse2::conic() const {
  Vector6d q = Vector6d::Zero();
  if (!(a > 0.0) || !(b > 0.0) || !std::isfinite(a) || !std::isfinite(b) || !std::isfinite(angle) ||
      !finite(center))
    return q;
  // (x - c)^T S (x - c) = 1 with S = R diag(1/a^2, 1/b^2) R^T.
  const double cs = std::cos(angle), sn = std::sin(angle);
  const double ia = 1.0 / (a * a), ib = 1.0 / (b * b);
  const double s11 = cs * cs * ia + sn * sn * ib;
  const double s12 = cs * sn * (ia - ib);
  const double s22 = sn * sn * ia + cs * cs * ib;
  const double cx = center.x(), cy = center.y();
  q << s11, 2.0 * s12, s22, -2.0 * (s11 * cx + s12 * cy), -2.0 * (s12 * cx + s22 * cy),
      s11 * cx * cx + 2.0 * s12 * cx * cy + s22 * cy * cy - 1.0;
  const double n = q.norm();
  if (!(n > 0.0) || !std::isfinite(n)) return Vector6d::Zero();
  return q / n;  // A + C > 0 already
}

EllipseTracker::EllipseTracker(const EllipseTrackerParams& params) : p_(sanitize(params)) {
  const auto n = static_cast<std::size_t>(p_.max_samples);
  const auto k = static_cast<std::size_t>(p_.max_candidates_per_line);
  tan_max_edge_ = static_cast<float>(std::tan(p_.max_edge_angle));
  cols_ = 2 * p_.half_length + 5;  // offsets -L-2..L+2: peaks at -L..L have both neighbours' support
  sample_index_.assign(n, 0);
  line_p_.assign(n, Eigen::Vector2d::Zero());
  line_n_.assign(n, Eigen::Vector2d::UnitX());
  line_lo_.assign(n, 0.0);
  line_hi_.assign(n, 0.0);
  profile_.assign(static_cast<std::size_t>(cols_), 0.0f);
  tangential_.assign(static_cast<std::size_t>(cols_), 0.0f);
  grad_.assign(static_cast<std::size_t>(cols_), 0.0f);
  inside_.assign(static_cast<std::size_t>(cols_), 0);
  cand_.assign(n * k, Candidate{Eigen::Vector2d::Zero(), Eigen::Vector2d::UnitX(), 0.0f, 0, 0});
  cand_count_.assign(n, 0);
  pool_.assign(n * k, 0);
  pool_cum_.assign(n * k, 0.0f);
  inlier_idx_.assign(n, 0);
  best_idx_.assign(n, 0);
  residual_.assign(n, 0.0);
  last_inliers_.reserve(n);
  last_inlier_samples_.reserve(n);
}

std::uint32_t EllipseTracker::next_random() {
  // xorshift32 (Marsaglia): period 2^32 - 1 on non-zero states.
  rng_ ^= rng_ << 13;
  rng_ ^= rng_ >> 17;
  rng_ ^= rng_ << 5;
  return rng_;
}

bool EllipseTracker::predict_ellipse(int n) {
  // Algebraic conic fit Q(x) = A x^2 + B xy + C y^2 + D x + E y + F to the samples' points
  // (Q(p) = 0) and normals (grad Q(p) x n = 0), Hartley-normalised: centred on the mean point,
  // scaled to a mean distance of sqrt(2). Exact for samples of an ellipse; the normals make a
  // short arc well-posed. Solution: eigenvector of the smallest eigenvalue of the scatter matrix.
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (int i = 0; i < n; ++i) mean += line_p_[i];
  mean /= n;
  double dist = 0.0;
  for (int i = 0; i < n; ++i) dist += (line_p_[i] - mean).norm();
  dist /= n;
  if (!(dist > 1e-9) || !std::isfinite(dist)) return false;
  const double k = dist / std::sqrt(2.0);  // pixels per normalised unit
  Matrix6d m = Matrix6d::Zero();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d x = (line_p_[i] - mean) / k;
    const Eigen::Vector2d& nn = line_n_[i];
    Vector6d row;
    row << x.x() * x.x(), x.x() * x.y(), x.y() * x.y(), x.x(), x.y(), 1.0;
    m.noalias() += row * row.transpose();
    // grad Q = (2Ax + By + D, Bx + 2Cy + E); grad Q x n = gx ny - gy nx.
    row << 2.0 * x.x() * nn.y(), x.y() * nn.y() - x.x() * nn.x(), -2.0 * x.y() * nn.x(), nn.y(), -nn.x(), 0.0;
    m.noalias() += row * row.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eig(m);
  if (eig.info() != Eigen::Success) return false;
  const Vector6d q = eig.eigenvectors().col(0);
  // Centre: grad Q(c) = 0; then Q(x) = (x - c)^T M (x - c) + Q(c), M = [A B/2; B/2 C].
  const double a = q[0], b2 = 0.5 * q[1], c = q[2];
  const double det = a * c - b2 * b2;
  if (!(std::abs(det) > 1e-12)) return false;
  const double cx = (-0.5 * q[3] * c + 0.5 * q[4] * b2) / det;
  const double cy = (-0.5 * q[4] * a + 0.5 * q[3] * b2) / det;
  const double qc = a * cx * cx + 2.0 * b2 * cx * cy + c * cy * cy + q[3] * cx + q[4] * cy + q[5];
  if (!(std::abs(qc) > 1e-15)) return false;
  // Shape in pixels: S = -M / (Q(c) k^2).
  const double f = -1.0 / (qc * k * k);
  const double s11 = a * f, s12 = b2 * f, s22 = c * f;
  Ellipse2 e;
  if (!shape_axes(s11, s12, s22, &e.a, &e.b, &e.angle)) return false;
  e.center = mean + k * Eigen::Vector2d(cx, cy);
  if (!(e.b >= kMinAxisPx) || !(e.a <= kMaxAxisPx) || !finite(e.center)) return false;
  predicted_ = e;
  origin_ = e.center;
  scale_ = std::sqrt(e.a * e.b);
  const double s2 = scale_ * scale_;
  prior_ << 0.0, 0.0, s11 * s2, s12 * s2, s22 * s2;

  // The samples must lie on the fitted ellipse (a projected circle, up to lens distortion).
  double sq = 0.0;
  for (int i = 0; i < n; ++i) {
    double r = 0.0;
    if (!sampson(prior_, (line_p_[i] - origin_) / scale_, &r, nullptr)) return false;
    sq += r * r;
  }
  const double rms_px = std::sqrt(sq / n) * scale_;
  return rms_px <= kMaxPredictionRmsFactor * p_.half_length;
}

void EllipseTracker::limit_line(int i) {
  // On the inner side the tracking lines converge towards the centres of curvature: beyond a
  // fraction of the radius of curvature they would cross each other, and a single clutter point
  // near the centre would be seen by many lines. Curvature of the level set of
  // f = u^T S u - 1: (f_yy f_x^2 - 2 f_xy f_x f_y + f_xx f_y^2) / |grad f|^3.
  const double half = p_.half_length;
  line_lo_[i] = -half;
  line_hi_[i] = half;
  const Eigen::Vector2d u = (line_p_[i] - origin_) / scale_;
  const double s11 = prior_[2], s12 = prior_[3], s22 = prior_[4];
  const double fx = 2.0 * (s11 * u.x() + s12 * u.y()), fy = 2.0 * (s12 * u.x() + s22 * u.y());
  const double g2 = fx * fx + fy * fy;
  if (!(g2 > 1e-24)) return;
  const double kappa = std::abs(2.0 * (s22 * fx * fx - 2.0 * s12 * fx * fy + s11 * fy * fy)) / (g2 * std::sqrt(g2));
  if (!(kappa > 0.0)) return;
  const double inner = std::min(half, kInnerCurvatureFraction * scale_ / kappa);  // pixels
  // The inner side is the one facing the centre.
  if (line_n_[i].dot(origin_ - line_p_[i]) > 0.0) {
    line_hi_[i] = inner;
  } else {
    line_lo_[i] = -inner;
  }
}

void EllipseTracker::search_line(const image::ImageView& img, int i, int want_sign) {
  const int half = p_.half_length + 2;  // profile offsets -half..half
  const int cols = cols_;
  const Eigen::Vector2d& p = line_p_[i];
  const Eigen::Vector2d& n = line_n_[i];
  const Eigen::Vector2d t(-n.y(), n.x());  // tangent: the two smoothing lines are at +-1 px along it
  const Eigen::Vector2d first = p - static_cast<double>(half) * n;
  const Eigen::Vector2d last = p + static_cast<double>(half) * n;
  const bool all_inside = img.contains(first.x() - t.x(), first.y() - t.y(), kInsideMargin) &&
                          img.contains(first.x() + t.x(), first.y() + t.y(), kInsideMargin) &&
                          img.contains(last.x() - t.x(), last.y() - t.y(), kInsideMargin) &&
                          img.contains(last.x() + t.x(), last.y() + t.y(), kInsideMargin);
  float* prof = profile_.data();
  float* gt = tangential_.data();
  if (all_inside) {
    // The four corners inside => every sample inside (the image is convex).
    for (int j = 0; j < cols; ++j) {
      const Eigen::Vector2d q = first + static_cast<double>(j) * n;
      const float minus = img.sample_inside(q.x() - t.x(), q.y() - t.y());
      const float plus = img.sample_inside(q.x() + t.x(), q.y() + t.y());
      prof[j] = (minus + img.sample_inside(q.x(), q.y()) + plus) * (1.0f / 3.0f);
      gt[j] = 0.5f * (plus - minus);
      inside_[j] = 1;
    }
  } else {
    // Sampled clamped, but marked so that no edge point comes from the clamped border extension.
    for (int j = 0; j < cols; ++j) {
      const Eigen::Vector2d q = first + static_cast<double>(j) * n;
      const double x0 = q.x() - t.x(), y0 = q.y() - t.y(), x2 = q.x() + t.x(), y2 = q.y() + t.y();
      const float minus = img.sample(x0, y0), plus = img.sample(x2, y2);
      prof[j] = (minus + img.sample(q.x(), q.y()) + plus) * (1.0f / 3.0f);
      gt[j] = 0.5f * (plus - minus);
      inside_[j] = (img.contains(x0, y0) && img.contains(x2, y2)) ? 1 : 0;
    }
  }
  // Central-difference gradient along the normal (grey levels per pixel).
  float* g = grad_.data();
  g[0] = 0.0f;
  g[cols - 1] = 0.0f;
  for (int j = 1; j < cols - 1; ++j) g[j] = 0.5f * (prof[j + 1] - prof[j - 1]);

  // Local maxima of sign * g at offsets -L..L (columns 2..cols-3); support j-2..j+2 inside.
  const int k_max = p_.max_candidates_per_line;
  const float tan_max = tan_max_edge_;
  Candidate* slots = &cand_[static_cast<std::size_t>(i) * k_max];
  int count = 0;
  int run = 0;  // consecutive inside columns ending at j + 2
  for (int j = 0; j < 4; ++j) run = inside_[j] ? run + 1 : 0;
  for (int j = 2; j < cols - 2; ++j) {
    run = inside_[j + 2] ? run + 1 : 0;
    if (run < 5) continue;
    const float gj = g[j];
    const int sign = gj > 0.0f ? 1 : -1;
    const float sg = sign * gj;
    if (!(sg >= p_.min_gradient) || sg <= 0.0f) continue;
    if (want_sign != 0 && sign != want_sign) continue;
    const float left = sign * g[j - 1], right = sign * g[j + 1];
    if (!(sg >= left && sg > right)) continue;
    // Direction: the tangential gradient (smoothed 1-2-1 along the normal, like the normal one is
    // across it) must be small against the normal one, which rejects most clutter edges crossing
    // the tracking line at an angle.
    const float g_tan = 0.25f * (gt[j - 1] + 2.0f * gt[j] + gt[j + 1]);
    if (std::abs(g_tan) > tan_max * sg) continue;
    // Sub-pixel peak: vertex of the parabola through the three values.
    const float denom = left - 2.0f * sg + right;
    float delta = denom < -1e-6f ? 0.5f * (left - right) / denom : 0.0f;
    delta = std::clamp(delta, -0.5f, 0.5f);
    const double offset = static_cast<double>(j - half) + delta;
    if (offset < line_lo_[i] || offset > line_hi_[i]) continue;
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
    const Eigen::Vector2d grad_dir = (static_cast<double>(gj) * n + static_cast<double>(g_tan) * t).normalized();
    slots[pos] = Candidate{(p + offset * n - origin_) / scale_, grad_dir, sg, sign, i};
  }
  cand_count_[i] = count;
}

EllipseTracker::Score EllipseTracker::score(const Params5& v, int sign, double tolerance_px) {
  // Each line holds at most one inlier: its candidate of the hypothesis' sign nearest the ellipse,
  // within the tolerance, whose image gradient is within kMaxInlierAngle of the ellipse's normal.
  const double tol = tolerance_px / scale_;
  const int n = static_cast<int>(cand_count_.size());
  const int k_max = p_.max_candidates_per_line;
  const double cx = v[0], cy = v[1], s11 = v[2], s12 = v[3], s22 = v[4];
  int count = 0;
  double sq = 0.0;
  for (int i = 0; i < n; ++i) {
    const int nc = cand_count_[i];
    int best = -1;
    double best_d = tol;
    for (int k = 0; k < nc; ++k) {
      const int idx = i * k_max + k;
      const Candidate& c = cand_[idx];
      if (c.sign != sign) continue;
      // Sampson distance f / |grad f| with f = u^T S u - 1, grad f = 2 S u (see sampson()).
      const double u1 = c.q.x() - cx, u2 = c.q.y() - cy;
      const double v1 = s11 * u1 + s12 * u2, v2 = s12 * u1 + s22 * u2;
      const double nv = std::sqrt(v1 * v1 + v2 * v2);
      if (!(nv > 1e-12)) continue;
      const double d = std::abs(u1 * v1 + u2 * v2 - 1.0) / (2.0 * nv);
      if (!(d <= best_d)) continue;
      if (std::abs(c.g.x() * v1 + c.g.y() * v2) < kCosMaxInlierAngle * nv) continue;
      best_d = d;
      best = idx;
    }
    if (best >= 0) {
      inlier_idx_[count++] = best;
      sq += best_d * best_d;
    }
  }
  Score sc;
  sc.count = count;
  sc.sq_px = sq * scale_ * scale_;
  sc.utility = static_cast<double>(count) - sq / (tol * tol);
  return sc;
}

bool EllipseTracker::fit(const int* idx, int count, int iterations, double sigma_px, Params5* v) const {
  // Gauss-Newton on sum_i (r_i / sigma)^2 + prior, r_i the Sampson distance (pixels) of edge
  // point i: the MAP estimate under edge noise sigma and a Gaussian prior centred on the
  // prediction, centre sigma L pixels, shape sigma kShapePriorFraction of the size (a change dS of
  // the normalised shape moves the curve by about dS / 2 normalised units). The prior only matters
  // in the directions the edge points do not constrain (a short arc).
  const double w_data = scale_ / sigma_px;
  const double w_centre = scale_ / static_cast<double>(p_.half_length);
  const double w_shape = 0.5 / kShapePriorFraction;
  Vector5d w_prior;
  w_prior << w_centre, w_centre, w_shape, w_shape, w_shape;
  const Vector5d w2 = w_prior.cwiseProduct(w_prior);

  auto objective = [&](const Vector5d& x, Matrix5d* h, Vector5d* g) -> double {
    const Vector5d dp = x - prior_;
    double cost = dp.cwiseProduct(dp).dot(w2);
    if (h != nullptr) {
      h->setZero();
      h->diagonal() = w2;
      *g = w2.cwiseProduct(dp);
    }
    for (int k = 0; k < count; ++k) {
      double r = 0.0;
      Vector5d jac;
      if (!sampson(x, cand_[idx[k]].q, &r, h != nullptr ? &jac : nullptr))
        return std::numeric_limits<double>::infinity();
      r *= w_data;
      cost += r * r;
      if (h != nullptr) {
        jac *= w_data;
        h->noalias() += jac * jac.transpose();
        *g += r * jac;
      }
    }
    return cost;
  };
  auto valid = [](const Vector5d& x) {
    return x.allFinite() && x[2] > 0.0 && x[4] > 0.0 && x[2] * x[4] - x[3] * x[3] > 0.0;
  };

  Vector5d x = *v;
  if (!valid(x)) return false;
  Matrix5d h;
  Vector5d g;
  double cost = objective(x, &h, &g);
  if (!std::isfinite(cost)) return false;
  for (int it = 0; it < iterations; ++it) {
    const Eigen::LDLT<Matrix5d> ldlt(h);
    if (ldlt.info() != Eigen::Success) break;
    const Vector5d step = -ldlt.solve(g);
    if (!step.allFinite()) break;
    // Backtracking: halve the step until the cost decreases and the shape stays an ellipse.
    double alpha = 1.0;
    bool accepted = false;
    for (int t = 0; t < 6; ++t, alpha *= 0.5) {
      const Vector5d trial = x + alpha * step;
      if (!valid(trial)) continue;
      const double c = objective(trial, nullptr, nullptr);
      if (c < cost) {
        x = trial;
        cost = c;
        accepted = true;
        break;
      }
    }
    if (!accepted) break;
    if (alpha * step.squaredNorm() < 1e-20) break;
    if (it + 1 < iterations) cost = objective(x, &h, &g);
  }
  *v = x;
  return true;
}

bool EllipseTracker::gate(const Params5& v) const {
  // The prediction gate: an ellipse, centre moved at most 2L, each semi-axis changed <= 30 %.
  double a = 0.0, b = 0.0, angle = 0.0;
  if (!shape_axes(v[2], v[3], v[4], &a, &b, &angle)) return false;
  a *= scale_;
  b *= scale_;
  const double shift = std::hypot(v[0], v[1]) * scale_;
  return shift <= kMaxCentreShiftFactor * p_.half_length &&
         std::abs(a - predicted_.a) <= kMaxAxisChange * predicted_.a &&
         std::abs(b - predicted_.b) <= kMaxAxisChange * predicted_.b;
}

Ellipse2 EllipseTracker::to_pixels(const Params5& v) const {
  Ellipse2 e;
  e.center = origin_ + scale_ * Eigen::Vector2d(v[0], v[1]);
  if (shape_axes(v[2], v[3], v[4], &e.a, &e.b, &e.angle)) {
    e.a *= scale_;
    e.b *= scale_;
  }
  return e;
}

EllipseMeasurement EllipseTracker::track(const image::ImageView& img, std::span<const CurveSample> predicted,
                                         EllipseTrackState& state) {
  EllipseMeasurement m;
  last_inliers_.clear();
  last_inlier_samples_.clear();
  std::fill(cand_count_.begin(), cand_count_.end(), 0);
  const std::size_t total = predicted.size();
  if (img.empty() || total < static_cast<std::size_t>(kMinSamples)) return m;

  // 1. Lines: all samples, or an evenly spaced subset of max_samples (fixed cost).
  const int n = static_cast<int>(std::min<std::size_t>(total, static_cast<std::size_t>(p_.max_samples)));
  for (int i = 0; i < n; ++i) {
    const auto idx = static_cast<std::size_t>(static_cast<unsigned long long>(i) * total / n);
    const CurveSample& s = predicted[idx];
    const double len = s.normal.norm();
    if (!finite(s.p) || !(len > 1e-6) || !std::isfinite(len)) return m;
    sample_index_[i] = static_cast<int>(idx);
    line_p_[i] = s.p;
    line_n_[i] = s.normal / len;
  }
  if (!predict_ellipse(n)) return m;

  // 2. Edge points along each line inside the image.
  const int want = state.polarity > 0 ? 1 : (state.polarity < 0 ? -1 : 0);
  int valid_lines = 0;
  int n_pos = 0, n_neg = 0;
  for (int i = 0; i < n; ++i) {
    if (!img.contains(line_p_[i].x(), line_p_[i].y(), kLineMargin)) continue;
    ++valid_lines;
    limit_line(i);
    search_line(img, i, want);
  }
  if (valid_lines < kMinInliers) return m;

  // Pool of candidates, positive signs first, with prefix sums of the strengths (weighted draws).
  const int k_max = p_.max_candidates_per_line;
  int pool_size = 0;
  for (int pass = 0; pass < 2; ++pass) {
    const int sign = pass == 0 ? 1 : -1;
    for (int i = 0; i < n; ++i)
      for (int k = 0; k < cand_count_[i]; ++k) {
        const int idx = i * k_max + k;
        if (cand_[idx].sign != sign) continue;
        pool_[pool_size] = idx;
        pool_cum_[pool_size] = (pool_size > 0 ? pool_cum_[pool_size - 1] : 0.0f) + cand_[idx].strength;
        ++pool_size;
        (sign > 0 ? n_pos : n_neg) += 1;
      }
  }
  if (pool_size < kMinInliers) return m;

  // 3. RANSAC over 5 edge points of one sign on distinct lines, weighted by gradient strength.
  rng_ = p_.seed != 0 ? p_.seed : kDefaultSeed;
  auto draw = [&](int lo, int hi) {  // pool position in [lo, hi), weighted
    const float base = lo > 0 ? pool_cum_[lo - 1] : 0.0f;
    const float span = pool_cum_[hi - 1] - base;
    const float r = base + static_cast<float>(next_random() >> 8) * (1.0f / 16777216.0f) * span;
    const int pos = static_cast<int>(std::upper_bound(pool_cum_.begin() + lo, pool_cum_.begin() + hi, r) -
                                     pool_cum_.begin());
    return std::min(pos, hi - 1);
  };
  // Hypotheses are ranked by the MSAC utility sum_inliers (1 - (d / tol)^2): at equal counts
  // (or nearly), the ellipse that passes closer to its edge points wins.
  const double tol = p_.inlier_tolerance;
  Score best;
  Params5 best_v = prior_;
  int best_sign = 0;
  int needed = p_.ransac_iterations;
  int chosen[kHypothesisSize];
  for (int it = 0; it < needed; ++it) {
    const int first = draw(0, pool_size);
    const int sign = cand_[pool_[first]].sign;
    const int lo = sign > 0 ? 0 : n_pos, hi = sign > 0 ? n_pos : pool_size;
    if (hi - lo < kHypothesisSize) continue;
    chosen[0] = pool_[first];
    bool ok = true;
    for (int s = 1; s < kHypothesisSize && ok; ++s) {
      ok = false;
      for (int r = 0; r < kRedraws && !ok; ++r) {
        const int idx = pool_[draw(lo, hi)];
        bool fresh = true;
        for (int t = 0; t < s; ++t) fresh = fresh && cand_[chosen[t]].line != cand_[idx].line;
        if (fresh) {
          chosen[s] = idx;
          ok = true;
        }
      }
    }
    if (!ok) continue;
    Params5 v = prior_;
    if (!fit(chosen, kHypothesisSize, kHypothesisIterations, tol, &v) || !gate(v)) continue;
    const Score sc = score(v, sign, tol);
    if (!(sc.utility > best.utility)) continue;
    best = sc;
    best_v = v;
    best_sign = sign;
    std::copy_n(inlier_idx_.begin(), sc.count, best_idx_.begin());
    // Local optimisation: a refit on the new best hypothesis' inliers, kept when it scores better.
    if (sc.count >= kHypothesisSize) {
      Params5 lv = v;
      if (fit(best_idx_.data(), sc.count, kHypothesisIterations, tol, &lv) && gate(lv)) {
        const Score lsc = score(lv, sign, tol);
        if (lsc.utility > best.utility) {
          best = lsc;
          best_v = lv;
          std::copy_n(inlier_idx_.begin(), lsc.count, best_idx_.begin());
        }
      }
    }
    // Adaptive stop: iterations for an all-inlier draw with probability kRansacConfidence.
    const double w = static_cast<double>(best.count) / (best_sign > 0 ? n_pos : n_neg);
    const double p_good = std::pow(std::min(w, 1.0), kHypothesisSize);
    if (p_good >= 1.0 - 1e-12) {
      needed = std::min(needed, it + 1);
    } else if (p_good > 0.0) {
      const double k = std::log(1.0 - kRansacConfidence) / std::log(1.0 - p_good);
      if (k < static_cast<double>(needed)) needed = std::max(it + 1, static_cast<int>(std::ceil(k)));
    }
  }
  if (best.count < kHypothesisSize) return m;

  // 4. Refinement: least squares on the inliers, inliers recomputed, while the utility improves
  // and until the inlier set is stable.
  Params5 v = best_v;
  Score cur = best;
  auto refine = [&](double tolerance_px, double sigma_px) {
    for (int round = 0; round < kRefineRounds; ++round) {
      Params5 rv = v;
      if (!fit(best_idx_.data(), cur.count, kRefineIterations, sigma_px, &rv) || !gate(rv)) return;
      const Score rsc = score(rv, best_sign, tolerance_px);
      if (rsc.count < kHypothesisSize || rsc.utility < cur.utility) return;
      bool same = rsc.count == cur.count;
      for (int k = 0; k < rsc.count && same; ++k) same = inlier_idx_[k] == best_idx_[k];
      v = rv;
      cur = rsc;
      std::copy_n(inlier_idx_.begin(), rsc.count, best_idx_.begin());
      if (same) return;
    }
  };
  refine(tol, tol);
  // Then the tolerance shrinks to kFinalSigmas robust standard deviations sigma of the residuals
  // (1.4826 x median |r|), bounded below by kMinFinalToleranceFraction x inlier_tolerance: clutter
  // edge points that pass within inlier_tolerance of the ellipse by chance leave the fit. The last
  // fit weighs the edge points by that sigma (at least kMinEdgeSigmaPx) against the prior.
  for (int k = 0; k < cur.count; ++k) {
    double r = 0.0;
    residual_[k] = sampson(v, cand_[best_idx_[k]].q, &r, nullptr) ? std::abs(r) * scale_ : 0.0;
  }
  std::nth_element(residual_.begin(), residual_.begin() + cur.count / 2, residual_.begin() + cur.count);
  const double sigma = kMadToSigma * residual_[cur.count / 2];
  const double final_tol = std::clamp(kFinalSigmas * sigma, kMinFinalToleranceFraction * tol, tol);
  if (final_tol < tol) {
    const Score tsc = score(v, best_sign, final_tol);
    if (tsc.count >= kHypothesisSize) {
      cur = tsc;
      std::copy_n(inlier_idx_.begin(), tsc.count, best_idx_.begin());
    }
  }
  refine(final_tol, std::clamp(sigma, kMinEdgeSigmaPx, tol));
  const int count = cur.count;

  // 5. Measurement in pixels.
  for (int k = 0; k < count; ++k) {
    const Candidate& c = cand_[best_idx_[k]];
    last_inliers_.push_back(origin_ + scale_ * c.q);
    last_inlier_samples_.push_back(sample_index_[c.line]);
  }
  m.ellipse = to_pixels(v);
  m.inliers = count;
  m.inlier_ratio = static_cast<double>(count) / valid_lines;
  m.rms_px = std::sqrt(cur.sq_px / count);
  m.polarity = best_sign;
  m.found = count >= kMinInliers && m.inlier_ratio >= p_.min_inlier_ratio && gate(v);
  if (m.found) state.polarity = m.polarity;
  return m;
}

}  // namespace v4r::features
