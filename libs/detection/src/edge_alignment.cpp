// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/edge_alignment.hpp"

#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

#include "v4r/geometry/se3_jacobians.hpp"
#include "v4r/image/image_view.hpp"

namespace v4r::detection {

namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;

/// Nearest pixel index, floor(v + 0.5) (std::lround is a library call in this inner loop);
/// a coordinate far outside any image gives an index every bounds test rejects.
inline int round_px(double v) {
  if (!(v > -1e6 && v < 1e6)) return -1000000;
  const double h = v + 0.5;
  const int i = static_cast<int>(h);
  return h < i ? i - 1 : i;
}

/// The image box of edge samples (px, rounded outwards).
PixelBox sample_box(std::span<const EdgeSample> s) {
  if (s.empty()) return {};
  double x0 = s[0].px.x(), x1 = x0, y0 = s[0].px.y(), y1 = y0;
  for (const EdgeSample& e : s) {
    x0 = std::min(x0, e.px.x());
    x1 = std::max(x1, e.px.x());
    y0 = std::min(y0, e.px.y());
    y1 = std::max(y1, e.px.y());
  }
  return {static_cast<int>(std::floor(x0)), static_cast<int>(std::floor(y0)), static_cast<int>(std::ceil(x1)),
          static_cast<int>(std::ceil(y1))};
}
}

EdgeAligner::EdgeAligner(const model::Model& model, const geometry::PinholeCamera& cam, const DetectorParams& p)
    : cam_(cam),
      p_(p.verify),
      threshold_{p.verify.min_gradient, p.verify.min_gradient_floor, p.verify.noise_factor},
      min_sobel2_(64.0 * p.verify.min_gradient * p.verify.min_gradient),
      cos_match_(std::cos(p.verify.match_angle_deg * kDeg)),
      cos_search_(std::cos(std::min(80.0, 1.5 * p.verify.match_angle_deg) * kDeg)),
      projector_(model, p.templates.crease_angle_deg * kDeg),
      samples_(static_cast<std::size_t>(std::max(16, p.verify.max_samples))),
      matched_(samples_.size(), 0),
      continued_(samples_.size(), 0),
      own_(static_cast<std::size_t>(std::max(0, cam.width)) * static_cast<std::size_t>(std::max(0, cam.height)), 0),
      twin_px_(samples_.size()),
      twin_matched_(samples_.size(), 0),
      twin_residual_(samples_.size(), 0.0f),
      contrast_(features::SilhouetteContrastParams{.min_group_samples = p.verify.leak_group_samples}) {}

double EdgeAligner::search(const GradientPyramid& g, const Eigen::Vector2d& px, const Eigen::Vector2d& n,
                           double range) const {
  const int w = g.width(), h = g.height();
  double best = 0.0, best_t = std::numeric_limits<double>::quiet_NaN();
  const int steps = static_cast<int>(range);
  for (int k = -steps; k <= steps; ++k) {
    const int x = round_px(px.x() + k * n.x());
    const int y = round_px(px.y() + k * n.y());
    if (x < 1 || y < 1 || x >= w - 1 || y >= h - 1) continue;
    const double gx = g.gx(x, y), gy = g.gy(x, y);
    const double m2 = gx * gx + gy * gy;
    if (m2 < min_sobel2_) continue;
    const double dot = std::abs(gx * n.x() + gy * n.y());
    if (dot * dot < cos_search_ * cos_search_ * m2) continue;
    // The strongest aligned gradient, nearer ones preferred a little.
    const double s = dot * (1.0 - 0.5 * std::abs(k) / (steps + 1.0));
    if (s > best) {
      best = s;
      best_t = k;
    }
  }
  return best_t;
}

double EdgeAligner::plateau_centre(const GradientPyramid& g, const EdgeSample& s, int k0) const {
  constexpr int kReach = 16;  // px either side of the match
  const int w = g.width(), h = g.height();
  // Gradient along the normal at px + k n, signed by the match's polarity; 0 where weak or not
  // aligned.
  double sign = 1.0;
  const auto along = [&](int k) {
    const int x = round_px(s.px.x() + k * s.normal.x());
    const int y = round_px(s.px.y() + k * s.normal.y());
    if (x < 1 || y < 1 || x >= w - 1 || y >= h - 1) return 0.0;
    const double gx = g.gx(x, y), gy = g.gy(x, y);
    const double m2 = gx * gx + gy * gy;
    const double dot = gx * s.normal.x() + gy * s.normal.y();
    if (m2 < min_sobel2_ || dot * dot < cos_search_ * cos_search_ * m2) return 0.0;
    return sign * dot;
  };
  const double d0 = along(k0);
  if (d0 == 0.0) return k0;
  sign = d0 > 0.0 ? 1.0 : -1.0;
  // The run of same-polarity edge pixels through k0 (kept, k0 - kReach .. k0 + kReach).
  std::array<double, 2 * kReach + 1> run{};
  run[kReach] = std::abs(d0);
  int lo = 0, hi = 0;
  while (lo > -kReach && (run[kReach + lo - 1] = along(k0 + lo - 1)) > 0.0) --lo;
  while (hi < kReach && (run[kReach + hi + 1] = along(k0 + hi + 1)) > 0.0) ++hi;
  double peak = 0.0;
  for (int k = lo; k <= hi; ++k) peak = std::max(peak, run[kReach + k]);
  // Its pixels at half the peak or more: the plateau, located at its centroid when wide.
  double sw = 0.0, swk = 0.0;
  int wide = 0;
  for (int k = lo; k <= hi; ++k) {
    const double d = run[kReach + k];
    if (d < 0.5 * peak) continue;
    sw += d;
    swk += d * k;
    ++wide;
  }
  return wide >= p_.plateau_px && sw > 0.0 ? k0 + swk / sw : static_cast<double>(k0);
}

void EdgeAligner::set_threshold(const GradientPyramid& g) {
  const double t = threshold_.at(g.noise());
  min_sobel2_ = 64.0 * t * t;  // Sobel is 8x the gradient
}

std::span<EdgeSample> EdgeAligner::refine_buffer() {
  return std::span<EdgeSample>(samples_).first(
      std::min(samples_.size(), static_cast<std::size_t>(std::max(16, p_.refine_samples))));
}

double EdgeAligner::loose_share(const GradientPyramid& g, const geometry::SE3& T, double range) {
  const std::size_t n = projector_.sample(T, cam_, p_.sample_spacing_px, refine_buffer());
  if (n < 12) return 0.0;
  int hit = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isnan(search(g, samples_[i].px, samples_[i].normal, range))) ++hit;
  return static_cast<double>(hit) / static_cast<double>(n);
}

int EdgeAligner::refine(const GradientPyramid& g, geometry::SE3& T) {
  set_threshold(g);
  int moved = 0;
  if (p_.depth_scan_steps > 0) {
    // Scale is what a template grid samples most coarsely: scan the distance first.
    const geometry::SE3 T0 = T;
    double best = loose_share(g, T0, 2.0 * p_.match_distance_px);
    for (int k = -p_.depth_scan_steps; k <= p_.depth_scan_steps; ++k) {
      if (k == 0) continue;
      geometry::SE3 Tk = T0;
      Tk.set_translation(T0.translation() * (1.0 + k * p_.depth_scan_step));
      const double s = loose_share(g, Tk, 2.0 * p_.match_distance_px);
      if (s > best) {
        best = s;
        T = Tk;
      }
    }
  }
  const int iters = p_.refine_iterations;
  for (int it = 0; it < iters; ++it) {
    // Search range: full for the first third, then shrinking to 2 match distances.
    const double f = iters <= 1 ? 0.0 : static_cast<double>(it) / (iters - 1);
    const double range = std::max(2.0 * p_.match_distance_px, p_.refine_search_px * (f < 0.34 ? 1.0 : (1.0 - f) * 1.5));
    const std::size_t n = projector_.sample(T, cam_, p_.sample_spacing_px, refine_buffer());
    if (n < 12) break;
    // Huber while the range is wide; then Tukey's biweight: a sample matched farther than
    // refine_tukey_px (an occluder's edge, a texture line) no longer pulls the pose.
    geometry::Vector6d delta;
    if (!align_step(g, n, range, f >= 0.34 ? p_.refine_tukey_px : 0.0, false, T, delta)) break;
    ++moved;
    if (delta.head<3>().norm() < 1e-6 && delta.tail<3>().norm() < 1e-6 && range <= 2.0 * p_.match_distance_px) break;
  }
  return moved;
}

int EdgeAligner::polish(const GradientPyramid& g, geometry::SE3& T) {
  set_threshold(g);
  int moved = 0;
  for (int it = 0; it < p_.polish_iterations; ++it) {
    const std::size_t n = projector_.sample(T, cam_, p_.sample_spacing_px, samples_);
    if (n < 12) break;
    geometry::Vector6d delta;
    if (!align_step(g, n, p_.polish_range_px, p_.polish_range_px, true, T, delta)) break;
    ++moved;
    if (delta.head<3>().norm() < 1e-7 && delta.tail<3>().norm() < 1e-7) break;
  }
  return moved;
}

double EdgeAligner::parabola_peak(const GradientPyramid& g, const Eigen::Vector2d& px, const Eigen::Vector2d& n,
                                  double t) const {
  const int w = g.width(), h = g.height();
  // |gradient . n| at t - 1, t, t + 1 (pixels nearest the normal's points).
  double v[3];
  for (int k = -1; k <= 1; ++k) {
    const int x = round_px(px.x() + (t + k) * n.x());
    const int y = round_px(px.y() + (t + k) * n.y());
    if (x < 1 || y < 1 || x >= w - 1 || y >= h - 1) return t;
    v[k + 1] = std::abs(g.gx(x, y) * n.x() + g.gy(x, y) * n.y());
  }
  const double denom = v[0] - 2.0 * v[1] + v[2];
  if (!(denom < -1e-9) || v[0] > v[1] || v[2] > v[1]) return t;
  return t + std::clamp(0.5 * (v[0] - v[2]) / denom, -0.5, 0.5);
}

bool EdgeAligner::align_step(const GradientPyramid& g, std::size_t n, double range, double tukey_px, bool subpixel,
                             geometry::SE3& T, geometry::Vector6d& delta) {
  geometry::Matrix6d H = geometry::Matrix6d::Zero();
  geometry::Vector6d b = geometry::Vector6d::Zero();
  int used = 0;
  const double huber = 1.5;
  const bool plateaus = p_.plateau_px > 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const EdgeSample& s = samples_[i];
    double t = search(g, s.px, s.normal, range);
    if (std::isnan(t)) continue;
    const double c = plateaus ? plateau_centre(g, s, static_cast<int>(t)) : t;
    if (c != t) t = c;
    else if (subpixel) t = parabola_peak(g, s.px, s.normal, t);
    const Eigen::Vector3d Xc = T * s.p_obj;
    const double z = Xc.z();
    if (z <= 1e-6) continue;
    const geometry::Vector6d J = geometry::normal_motion_jacobian(Xc, s.normal, cam_.fx, cam_.fy);
    const double r = -t;  // residual: projected point minus the matched edge, along n
    double w = std::abs(r) <= huber ? 1.0 : huber / std::abs(r);
    if (tukey_px > 0.0) {
      const double u = r / tukey_px;
      w = std::abs(u) < 1.0 ? (1.0 - u * u) * (1.0 - u * u) : 0.0;
    }
    H.noalias() += w * J * J.transpose();
    b.noalias() += w * r * J;
    ++used;
  }
  if (used < 12) return false;
  H.diagonal() *= 1.0 + 1e-3;
  H.diagonal().array() += 1e-9;
  delta = H.ldlt().solve(-b);
  if (!delta.allFinite()) return false;
  T = geometry::SE3::exp(delta) * T;
  return true;
}

Eigen::Vector3d EdgeAligner::visible_centroid(const geometry::SE3& T, const Eigen::Vector3d& fallback) {
  const std::size_t n = projector_.sample(T, cam_, p_.sample_spacing_px, samples_);
  if (n == 0) return fallback;
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) m += samples_[i].p_obj;
  return m / static_cast<double>(n);
}

void EdgeAligner::paint_own(std::size_t n, std::uint8_t value) {
  constexpr int kOwn = 3;  // px: a probe this close to one of the pose's samples is on its own edges
  const int w = cam_.width, h = cam_.height;
  for (std::size_t i = 0; i < n; ++i) {
    const int cx = round_px(samples_[i].px.x()), cy = round_px(samples_[i].px.y());
    for (int y = std::max(0, cy - kOwn); y <= std::min(h - 1, cy + kOwn); ++y)
      for (int x = std::max(0, cx - kOwn); x <= std::min(w - 1, cx + kOwn); ++x)
        own_[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)] = value;
  }
}

void EdgeAligner::mark_continued(const GradientPyramid& g, std::size_t n) {
  std::fill_n(continued_.begin(), n, std::uint8_t{0});
  if (!(p_.continued_reach > 0.0) || g.width() != cam_.width || g.height() != cam_.height) return;
  constexpr double kStep = 4.0, kMinReach = 12.0, kMaxReach = 40.0;  // px
  constexpr int kMinProbes = 3;
  const int w = g.width(), h = g.height();
  paint_own(n, 1);
  // A gradient of the edge's orientation (either polarity) within match_distance of q along n,
  // in half-pixel steps as verify looks for a sample's match.
  const int steps = static_cast<int>(std::ceil(p_.match_distance_px * 2.0));
  const auto matches_at = [&](const Eigen::Vector2d& q, const Eigen::Vector2d& nn) {
    for (int k = -steps; k <= steps; ++k) {
      if (0.5 * std::abs(k) > p_.match_distance_px) continue;
      const int x = round_px(q.x() + 0.5 * k * nn.x()), y = round_px(q.y() + 0.5 * k * nn.y());
      if (x < 1 || y < 1 || x >= w - 1 || y >= h - 1) return false;
      const double gx = g.gx(x, y), gy = g.gy(x, y), m2 = gx * gx + gy * gy;
      if (m2 < min_sobel2_) continue;
      const double dot = gx * nn.x() + gy * nn.y();
      if (dot * dot >= cos_match_ * cos_match_ * m2) return true;
    }
    return false;
  };
  // Whether the line goes on from `end` along `dir` for `reach` px: probes off the image or on
  // the pose's own edges are not counted.
  const auto continued = [&](const Eigen::Vector2d& end, const Eigen::Vector2d& dir, const Eigen::Vector2d& nn,
                             double reach) {
    int probes = 0, hits = 0;
    for (double t = kStep; t <= reach; t += kStep) {
      const Eigen::Vector2d q = end + t * dir;
      const int x = round_px(q.x()), y = round_px(q.y());
      if (x < 1 || y < 1 || x >= w - 1 || y >= h - 1) continue;
      if (own_[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)] != 0) continue;
      ++probes;
      hits += matches_at(q, nn) ? 1 : 0;
    }
    return probes >= kMinProbes && hits >= p_.continued_share * probes;
  };
  for (std::size_t a = 0; a < n;) {
    std::size_t b = a + 1;
    while (b < n && samples_[b].piece == samples_[a].piece) ++b;
    if (b - a >= static_cast<std::size_t>(std::max(2, p_.min_run))) {
      const Eigen::Vector2d p0 = samples_[a].px, p1 = samples_[b - 1].px;
      const double length = (p1 - p0).norm();
      if (length > 0.0) {
        const Eigen::Vector2d d = (p1 - p0) / length;
        const double reach = std::clamp(p_.continued_reach * length, kMinReach, kMaxReach);
        if (continued(p0, -d, samples_[a].normal, reach) && continued(p1, d, samples_[b - 1].normal, reach))
          std::fill(continued_.begin() + static_cast<long>(a), continued_.begin() + static_cast<long>(b), std::uint8_t{1});
      }
    }
    a = b;
  }
  paint_own(n, 0);
}

Verification EdgeAligner::verify(const GradientPyramid& g, const geometry::SE3& T) {
  set_threshold(g);
  Verification v;
  const std::size_t n = projector_.sample(T, cam_, p_.sample_spacing_px, samples_);
  v.samples = static_cast<int>(n);
  if (v.samples < p_.min_samples) return v;
  v.box = sample_box(std::span<const EdgeSample>(samples_.data(), n));
  const int w = g.width(), h = g.height();
  const int steps = static_cast<int>(std::ceil(p_.match_distance_px * 2.0));
  // A run: consecutive matches along one edge piece with one polarity (the same side brighter),
  // going on over up to detect.verify.run_gap unmatched samples in a row when a match of its
  // polarity follows (they do not count). A piece shorter than min_run samples counts when all
  // of it matches with one polarity.
  int run = 0, run_sign = 0, piece_samples = 0;
  int gap = 0;  // unmatched samples bridged since the run's last match
  bool piece_broken = false;
  std::uint32_t run_piece = n > 0 ? samples_[0].piece : 0;
  const auto close_run = [&](bool piece_end) {
    if (run >= p_.min_run || (p_.short_pieces && piece_end && !piece_broken && run == piece_samples && run > 0)) v.in_runs += run;
    if (!piece_end && run > 0) piece_broken = true;
    run = 0;
  };
  const int support = std::max(0, p_.tangent_support);
  // The gradient at offset t along a sample's normal, summed over `support` pixels either side
  // along the edge; false off the image.
  const auto gradient_at = [&](const EdgeSample& s, double t, double& gx, double& gy) {
    gx = gy = 0.0;
    for (int j = -support; j <= support; ++j) {
      const int x = round_px(s.px.x() + t * s.normal.x() - j * s.normal.y());
      const int y = round_px(s.px.y() + t * s.normal.y() + j * s.normal.x());
      if (x < 1 || y < 1 || x >= w - 1 || y >= h - 1) return false;
      gx += g.gx(x, y);
      gy += g.gy(x, y);
    }
    const double k = 1.0 / (2 * support + 1);
    gx *= k;
    gy *= k;
    return true;
  };
  mark_continued(g, n);
  for (std::size_t i = 0; i < n; ++i) {
    const EdgeSample& s = samples_[i];
    int sign = 0;
    double best = 0.0;
    for (int k = -steps; k <= steps; ++k) {
      const double t = 0.5 * k;
      if (std::abs(t) > p_.match_distance_px) continue;
      double gx = 0.0, gy = 0.0;
      if (!gradient_at(s, t, gx, gy)) continue;
      const double m2 = gx * gx + gy * gy;
      if (m2 < min_sobel2_) continue;
      const double dot = gx * s.normal.x() + gy * s.normal.y();
      if (dot * dot < cos_match_ * cos_match_ * m2 || std::abs(dot) <= best) continue;
      // An edge rather than the slope of a ramp: the gradient along the normal does not grow by
      // more than detect.verify.peak_tolerance one pixel further either way (shading and texture
      // ramps would otherwise match any nearby pose).
      bool peak = true;
      for (const int d : {-1, 1}) {
        double nx = 0.0, ny = 0.0;
        if (!gradient_at(s, t + d, nx, ny)) continue;
        const double next = std::abs(nx * s.normal.x() + ny * s.normal.y());
        if (next > p_.peak_tolerance * std::abs(dot)) peak = false;
      }
      if (!peak) continue;
      best = std::abs(dot);
      sign = dot > 0 ? 1 : -1;
    }
    const bool ok = sign != 0 && continued_[i] == 0;
    matched_[i] = ok ? 1 : 0;
    if (s.piece != run_piece) {
      close_run(true);
      piece_samples = 0;
      piece_broken = false;
      gap = 0;
    } else if (!ok && run > 0 && gap < p_.run_gap) {
      ++gap;  // bridged: the run goes on if a match of its polarity follows
      piece_broken = true;
    } else if (!ok || (run > 0 && sign != run_sign)) {
      close_run(false);
      gap = 0;
      if (!ok) piece_broken = true;
    }
    run_piece = s.piece;
    ++piece_samples;
    if (ok) {
      ++run;
      run_sign = sign;
      gap = 0;
    }
    v.matched += ok ? 1 : 0;
  }
  close_run(true);
  v.match_share = static_cast<double>(v.matched) / v.samples;
  v.score = static_cast<double>(v.in_runs) / v.samples;
  return v;
}

double EdgeAligner::edge_residual(const GradientPyramid& g, const EdgeSample& s) const {
  const double t = search(g, s.px, s.normal, kTwinReachPx);
  if (std::isnan(t)) return kTwinReachPx;
  return std::min(kTwinReachPx, std::abs(plateau_centre(g, s, static_cast<int>(t))));
}

EdgeAligner::TwinShares EdgeAligner::compare_twins(const GradientPyramid& g, const geometry::SE3& T_a,
                                                  const geometry::SE3& T_b, double px, bool residuals) {
  TwinShares r;
  const int na = verify(g, T_a).samples;
  if (na < p_.min_samples) return r;  // (verify matched none of them)
  for (int i = 0; i < na; ++i) {
    twin_px_[static_cast<std::size_t>(i)] = samples_[static_cast<std::size_t>(i)].px;
    twin_matched_[static_cast<std::size_t>(i)] = matched_[static_cast<std::size_t>(i)];
    if (residuals)
      twin_residual_[static_cast<std::size_t>(i)] = static_cast<float>(edge_residual(g, samples_[static_cast<std::size_t>(i)]));
  }
  const int nb = verify(g, T_b).samples;
  if (nb < p_.min_samples) return r;
  // samples_ and matched_ hold b's samples now, twin_px_ and twin_matched_ a's.
  const double px2 = px * px;
  const auto near_a = [&](const Eigen::Vector2d& q) {
    for (int j = 0; j < na; ++j)
      if ((twin_px_[static_cast<std::size_t>(j)] - q).squaredNorm() <= px2) return true;
    return false;
  };
  const auto near_b = [&](const Eigen::Vector2d& q) {
    for (int j = 0; j < nb; ++j)
      if ((samples_[static_cast<std::size_t>(j)].px - q).squaredNorm() <= px2) return true;
    return false;
  };
  int ma = 0, mb = 0;
  for (int i = 0; i < na; ++i) {
    if (near_b(twin_px_[static_cast<std::size_t>(i)])) continue;
    ++r.na;
    ma += twin_matched_[static_cast<std::size_t>(i)];
    if (residuals) r.residual_a += twin_residual_[static_cast<std::size_t>(i)];
  }
  for (int i = 0; i < nb; ++i) {
    if (near_a(samples_[static_cast<std::size_t>(i)].px)) continue;
    ++r.nb;
    mb += matched_[static_cast<std::size_t>(i)];
    if (residuals) r.residual_b += edge_residual(g, samples_[static_cast<std::size_t>(i)]);
  }
  r.a = r.na > 0 ? static_cast<double>(ma) / r.na : 0.0;
  r.b = r.nb > 0 ? static_cast<double>(mb) / r.nb : 0.0;
  if (residuals) {
    r.residual_a = r.na > 0 ? r.residual_a / r.na : kTwinReachPx;
    r.residual_b = r.nb > 0 ? r.residual_b / r.nb : kTwinReachPx;
  }
  return r;
}

void EdgeAligner::measure_leak(const image::ColourView& colour, const geometry::SE3& T, Verification& v) {
  v.leak = -1.0;
  v.leak_samples = 0;
  if (colour.empty()) return;
  const std::size_t n = projector_.sample(T, cam_, p_.sample_spacing_px, samples_);
  double probe = 0.0;
  for (const double d : contrast_.params().offsets_px) probe = std::max(probe, d);
  projector_.mark_sides(std::span<EdgeSample>(samples_).first(n), probe);
  contrast_.reset();
  for (std::size_t i = 0; i < n; ++i) {
    const EdgeSample& s = samples_[i];
    if (s.object_side == 0) continue;
    contrast_.add_point(image::ImageView{}, colour, s.px, s.object_side > 0 ? Eigen::Vector2d(-s.normal) : s.normal,
                        s.inside_extent_px, s.piece);
  }
  contrast_.finish();
  v.leak_samples = contrast_.samples();
  if (v.leak_samples > 0) v.leak = static_cast<double>(contrast_.leaked()) / v.leak_samples;
}

}  // namespace v4r::detection
