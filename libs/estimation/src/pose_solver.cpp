// v4r - robust model-based object tracking. MIT licence.
//
// Object-space pose solver after Wunsch (1997), paper section 5. Everything is computed in
// normalised units: each scalar residual is divided by its a-priori object-space sigma, so the
// normal matrix H = sum J^T J and the gradient g = sum J^T r are in units of sigma and the
// sum of squared residuals is chi-square distributed when the a-priori sigmas are right.
//
// Solve flow:
//   1. prepare: reject invalid input (non-finite, sigma <= 0, coincident line points), cache the
//      line-of-sight bases of the points and the interpretation-plane normals of the lines.
//   2. robust pass (optional): Gauss-Newton with Cauchy IRLS weights from T_init; the scale is
//      re-estimated every iteration from a low quantile of the residuals (never below the
//      a-priori sigma).
//      Observations whose residual at the robust pose exceeds the threshold are rejected.
//   3. remove-largest loop (Kraus): plain weighted least squares; the active observation with
//      the largest standardised residual (residual over its own standard deviation in the fit,
//      using the redundancy I - J H^-1 J^T) is removed while it exceeds the threshold.
//   4. once, rejected observations that agree with the final pose (predicted residual within the
//      threshold) are re-admitted and step 3 is repeated.
//   5. covariance max(sigma0, min_sigma0)^2 * H^-1, rms in pixels, inlier flags.

#include "v4r/estimation/pose_solver.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace v4r::estimation {

namespace {

using geometry::Matrix6d;
using geometry::SE3;
using geometry::Vector6d;

constexpr std::uint8_t kRejected = 0;
constexpr std::uint8_t kActive = 1;
constexpr std::uint8_t kInvalid = 2;
constexpr int kUnknowns = 6;
/// Quantile of the per-observation RMS residuals from which the noise scale is estimated. A low
/// quantile keeps the estimate meaningful with up to ~(1 - kScaleQuantile) gross errors (the
/// median breaks down at 50 %).
constexpr double kScaleQuantile = 0.3;
/// The RMS Y of two unit Gaussian residuals has P(Y <= y) = 1 - exp(-y^2): its quantile p is
/// sqrt(-ln(1 - p)), the reference that turns a residual quantile into a scale.
const double kScaleReference = std::sqrt(-std::log1p(-kScaleQuantile));
/// Relative standard error of the sample quantile p of Y from n values, times sqrt(n):
/// sqrt(p / (1 - p)) / (2 (-ln(1 - p))).
const double kScaleRelError =
    std::sqrt(kScaleQuantile / (1.0 - kScaleQuantile)) / (-2.0 * std::log1p(-kScaleQuantile));
/// Standard errors below the estimate at which the adaptive threshold's scale is taken.
constexpr double kScaleConfidence = 3.0;
/// Regularisation of the 2x2 residual cofactor matrix of an observation (units of sigma^2).
constexpr double kCofactorEps = 1e-6;

bool finite(const Eigen::Vector2d& v) { return v.allFinite(); }
bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }

/// Pose as rotation matrix + translation, for evaluating many points.
struct Rt {
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  explicit Rt(const SE3& T) : R(T.rotation()), t(T.translation()) {}
  Eigen::Vector3d operator()(const Eigen::Vector3d& X) const { return R * X + t; }
};

ResidualWeighting weighting(const PoseSolverParams& p) {
  ResidualWeighting w;
  w.focal_px = p.focal_px;
  w.oblique = p.oblique_weighting;
  w.min_depth = p.min_depth;
  return w;
}

/// Diagonal balancing S = diag(1, 1, 1, 1/L, 1/L, 1/L) that gives the rotation block of S H S the
/// trace of the translation block (L: a characteristic length, metres). Returns false when a
/// block is empty.
bool balance(const Matrix6d& H, Vector6d& s) {
  const double a = H.topLeftCorner<3, 3>().trace();
  const double b = H.bottomRightCorner<3, 3>().trace();
  if (!(a > 0.0) || !(b > 0.0) || !std::isfinite(a) || !std::isfinite(b)) return false;
  const double inv_l = std::sqrt(a / b);
  s << 1.0, 1.0, 1.0, inv_l, inv_l, inv_l;
  return true;
}

/// Inverse of the normal matrix via the eigen-decomposition of its balanced form; false when the
/// smallest / largest eigenvalue ratio is below `ratio`.
bool invert_normal(const Matrix6d& H, double ratio, Matrix6d& H_inv) {
  Vector6d s;
  if (!balance(H, s)) return false;
  const Matrix6d Hb = s.asDiagonal() * H * s.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix6d> es(Hb);
  if (es.info() != Eigen::Success) return false;
  const Vector6d& ev = es.eigenvalues();  // ascending
  if (!(ev(5) > 0.0) || !(ev(0) > ratio * ev(5))) return false;
  const Matrix6d Hb_inv = es.eigenvectors() * ev.cwiseInverse().asDiagonal() * es.eigenvectors().transpose();
  H_inv = s.asDiagonal() * Hb_inv * s.asDiagonal();
  return H_inv.allFinite();
}

}  // namespace

void PoseSolver::reserve(std::size_t points, std::size_t lines) {
  active_pts_.reserve(points);
  point_bases_.reserve(points);
  rho_pts_.reserve(points);
  stat_pts_.reserve(points);
  active_lines_.reserve(lines);
  line_normals_.reserve(lines);
  rho_lines_.reserve(lines);
  stat_lines_.reserve(lines);
  scratch_.reserve(points + lines);
}

void PoseSolver::prepare(std::span<const PointObservation> points, std::span<const LineObservation> lines) {
  active_pts_.resize(points.size());
  point_bases_.resize(points.size());
  rho_pts_.assign(points.size(), 1.0);
  stat_pts_.assign(points.size(), 0.0);
  active_lines_.resize(lines.size());
  line_normals_.resize(lines.size());
  rho_lines_.assign(lines.size(), 1.0);
  stat_lines_.assign(lines.size(), 0.0);
  scratch_.resize(points.size() + lines.size());

  for (std::size_t i = 0; i < points.size(); ++i) {
    const PointObservation& o = points[i];
    const bool ok = finite(o.X_obj) && finite(o.xn) && std::isfinite(o.sigma_px) && o.sigma_px > 0.0;
    active_pts_[i] = ok ? kActive : kInvalid;
    if (ok) point_bases_[i] = ray_basis(o.xn);
  }
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const LineObservation& o = lines[i];
    bool ok = finite(o.X1_obj) && finite(o.X2_obj) && finite(o.xn1) && finite(o.xn2) && std::isfinite(o.sigma_px) &&
              o.sigma_px > 0.0;
    if (ok) {
      line_normals_[i] = interpretation_plane_normal(o.xn1, o.xn2);
      ok = line_normals_[i].squaredNorm() > 0.5;
    }
    active_lines_[i] = ok ? kActive : kInvalid;
  }
}

int PoseSolver::count_active() const {
  return static_cast<int>(std::count(active_pts_.begin(), active_pts_.end(), kActive) +
                          std::count(active_lines_.begin(), active_lines_.end(), kActive));
}

PoseSolver::Normal PoseSolver::linearise(const SE3& T, std::span<const PointObservation> points,
                                         std::span<const LineObservation> lines, bool robust) const {
  Normal ne;
  const Rt rt(T);
  const ResidualWeighting w = weighting(p_);
  Eigen::Vector2d rw;
  Matrix26d Jw;
  const auto add = [&](double rho, double sigma_px) {
    // Upper triangle of H += rho J^T J (two rank-1 updates), mirrored after the loop.
    for (int k = 0; k < 2; ++k) {
      for (int i = 0; i < 6; ++i) {
        const double a = rho * Jw(k, i);
        ne.g(i) += a * rw(k);
        for (int j = i; j < 6; ++j) ne.H(i, j) += a * Jw(k, j);
      }
    }
    const double sq = rw.squaredNorm();
    ne.chi2 += sq;
    ne.sum_sq_px += sq * sigma_px * sigma_px;
    ne.residuals += 2;
  };
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (active_pts_[i] != kActive) continue;
    const PointObservation& o = points[i];
    ne.behind += normalised_point_residual(rt(o.X_obj), point_bases_[i], o.sigma_px, w, rw, &Jw) ? 1 : 0;
    add(robust ? rho_pts_[i] : 1.0, o.sigma_px);
  }
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (active_lines_[i] != kActive) continue;
    const LineObservation& o = lines[i];
    const bool behind = normalised_line_residual(rt(o.X1_obj), rt(o.X2_obj), line_normals_[i], o.sigma_px, w, rw, &Jw);
    ne.behind += behind ? 1 : 0;
    add(robust ? rho_lines_[i] : 1.0, o.sigma_px);
  }
  ne.H.triangularView<Eigen::StrictlyLower>() = ne.H.transpose();
  return ne;
}

void PoseSolver::statistics(const SE3& T, const Matrix6d& H_inv, std::span<const PointObservation> points,
                            std::span<const LineObservation> lines, Statistic kind) {
  const Rt rt(T);
  const ResidualWeighting w = weighting(p_);
  Eigen::Vector2d rw;
  Matrix26d Jw;
  Matrix26d* const J = kind == Statistic::kPlain ? nullptr : &Jw;
  const auto stat = [&](std::uint8_t state) {
    if (kind == Statistic::kPlain) return std::sqrt(0.5 * rw.squaredNorm());
    // Cofactor of the residual: I - J H^-1 J^T for an observation in the fit (its redundancy),
    // I + J H^-1 J^T for one left out (prediction error of the pose adds to its own noise).
    const Eigen::Matrix2d M = Jw * H_inv * Jw.transpose();
    Eigen::Matrix2d Q = state == kActive ? Eigen::Matrix2d(Eigen::Matrix2d::Identity() - M)
                                         : Eigen::Matrix2d(Eigen::Matrix2d::Identity() + M);
    Q.diagonal().array() += kCofactorEps;
    const double t = rw.dot(Q.inverse() * rw);
    return std::sqrt(0.5 * std::max(t, 0.0));
  };
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (active_pts_[i] == kInvalid) continue;
    const PointObservation& o = points[i];
    normalised_point_residual(rt(o.X_obj), point_bases_[i], o.sigma_px, w, rw, J);
    stat_pts_[i] = stat(active_pts_[i]);
  }
  for (std::size_t i = 0; i < lines.size(); ++i) {
    if (active_lines_[i] == kInvalid) continue;
    const LineObservation& o = lines[i];
    normalised_line_residual(rt(o.X1_obj), rt(o.X2_obj), line_normals_[i], o.sigma_px, w, rw, J);
    stat_lines_[i] = stat(active_lines_[i]);
  }
}

double PoseSolver::quantile_scale() {
  std::size_t n = 0;
  for (std::size_t i = 0; i < active_pts_.size(); ++i)
    if (active_pts_[i] == kActive) scratch_[n++] = stat_pts_[i];
  for (std::size_t i = 0; i < active_lines_.size(); ++i)
    if (active_lines_[i] == kActive) scratch_[n++] = stat_lines_[i];
  if (n == 0) return 1.0;
  const auto q = scratch_.begin() + static_cast<std::ptrdiff_t>(kScaleQuantile * static_cast<double>(n - 1));
  std::nth_element(scratch_.begin(), q, scratch_.begin() + static_cast<std::ptrdiff_t>(n));
  return *q / kScaleReference;
}

void PoseSolver::update_robust_weights(double scale) {
  const double c = p_.cauchy_c * scale;
  const auto cauchy = [c](double s) {
    const double u = s / c;
    return 1.0 / (1.0 + u * u);
  };
  for (std::size_t i = 0; i < active_pts_.size(); ++i) rho_pts_[i] = cauchy(stat_pts_[i]);
  for (std::size_t i = 0; i < active_lines_.size(); ++i) rho_lines_[i] = cauchy(stat_lines_[i]);
}

SolveStatus PoseSolver::gauss_newton(SE3& T, std::span<const PointObservation> points,
                                     std::span<const LineObservation> lines, bool robust, int max_iterations,
                                     int& iterations, bool& converged, Normal& last) {
  converged = false;
  const Matrix6d no_inverse = Matrix6d::Zero();
  const auto relinearise = [&]() {
    if (robust) {
      statistics(T, no_inverse, points, lines, Statistic::kPlain);
      update_robust_weights(std::max(1.0, quantile_scale()));
    }
    last = linearise(T, points, lines, robust);
  };
  relinearise();
  for (int it = 0; it < max_iterations; ++it) {
    if (last.residuals < kUnknowns || count_active() < std::max(p_.min_observations, 1))
      return SolveStatus::kTooFewObservations;
    if (!last.H.allFinite() || !last.g.allFinite()) return SolveStatus::kDiverged;
    Vector6d s;
    if (!balance(last.H, s)) return SolveStatus::kDegenerate;
    const Matrix6d Hb = s.asDiagonal() * last.H * s.asDiagonal();
    const Eigen::LDLT<Matrix6d> ldlt(Hb);
    if (ldlt.info() != Eigen::Success) return SolveStatus::kDegenerate;
    const Vector6d d = ldlt.vectorD().cwiseAbs();
    if (!(d.minCoeff() > p_.degeneracy_ratio * d.maxCoeff())) return SolveStatus::kDegenerate;
    const Vector6d delta = -(s.asDiagonal() * ldlt.solve(s.asDiagonal() * last.g)).eval();
    if (!delta.allFinite()) return SolveStatus::kDiverged;
    T = SE3::exp(delta) * T;
    ++iterations;
    relinearise();
    if (delta.norm() < (robust ? p_.robust_step_tolerance : p_.step_tolerance)) {
      converged = true;
      break;
    }
  }
  if (!T.translation().allFinite() || !T.quaternion().coeffs().allFinite()) return SolveStatus::kDiverged;
  return SolveStatus::kOk;
}

PoseResult PoseSolver::solve(const SE3& T_init, std::span<const PointObservation> points,
                             std::span<const LineObservation> lines, std::span<std::uint8_t> point_inlier,
                             std::span<std::uint8_t> line_inlier) {
  PoseResult res;
  res.T_cam_obj = T_init;
  res.observations = static_cast<int>(points.size() + lines.size());
  prepare(points, lines);

  const auto finish = [&](SolveStatus status) {
    res.status = status;
    res.inliers = count_active();
    if (point_inlier.size() == points.size())
      for (std::size_t i = 0; i < points.size(); ++i) point_inlier[i] = active_pts_[i] == kActive ? 1 : 0;
    if (line_inlier.size() == lines.size())
      for (std::size_t i = 0; i < lines.size(); ++i) line_inlier[i] = active_lines_[i] == kActive ? 1 : 0;
    return res;
  };

  if (!T_init.translation().allFinite() || !T_init.quaternion().coeffs().allFinite())
    return finish(SolveStatus::kDiverged);
  if (!(p_.focal_px > 0.0) || !std::isfinite(p_.focal_px)) return finish(SolveStatus::kDegenerate);
  if (count_active() < std::max(p_.min_observations, 1)) return finish(SolveStatus::kTooFewObservations);

  const bool detect = p_.max_outlier_rounds > 0 && p_.outlier_threshold > 0.0;
  SE3 T = T_init;
  Normal ne;
  bool converged = false;
  double scale = 1.0;

  // 2. Robust pass: a starting pose that gross errors have not pulled, and a first inlier set.
  if (detect && p_.robust_init) {
    SE3 T_r = T;
    const SolveStatus st =
        gauss_newton(T_r, points, lines, /*robust=*/true, p_.robust_max_iterations, res.iterations, converged, ne);
    if (st == SolveStatus::kOk) {
      T = T_r;
      statistics(T, Matrix6d::Zero(), points, lines, Statistic::kPlain);
      // Noise scale from a low quantile of the residuals, corrected for the shrinking of
      // residuals by the fit (redundancy fraction). The threshold only widens when the scale is
      // significantly above 1: its lower 3-standard-error confidence bound is used, so that the
      // noisy estimate from few observations does not cost detection power.
      const int n_active = count_active();
      const double redundancy = std::max(1.0 - static_cast<double>(kUnknowns) / (2.0 * n_active), 0.1);
      res.noise_scale = quantile_scale() / std::sqrt(redundancy);
      const double lower_bound =
          res.noise_scale / (1.0 + kScaleConfidence * kScaleRelError / std::sqrt(n_active));
      scale = p_.adaptive_threshold ? std::max(1.0, lower_bound) : 1.0;
      const bool scale_plausible = scale <= p_.max_threshold_scale;
      const double thr = p_.outlier_threshold * scale;
      int gross = 0;
      for (std::size_t i = 0; i < points.size(); ++i) gross += active_pts_[i] == kActive && stat_pts_[i] > thr;
      for (std::size_t i = 0; i < lines.size(); ++i) gross += active_lines_[i] == kActive && stat_lines_[i] > thr;
      // A robust fit that disagrees with most observations, or whose residuals are many times
      // the a-priori sigma, was most likely pulled by gross errors (IRLS breaks down well below
      // 50 % contamination when the errors pull coherently): it does not decide, and neither
      // does its scale. The remove-largest loop takes over from T_init with the a-priori
      // threshold (slower, but it copes with higher contamination by large errors).
      const int active = count_active();
      if (!scale_plausible || 2 * gross > active || active - gross < p_.min_observations) {
        T = T_init;
        scale = 1.0;
      } else {
        for (std::size_t i = 0; i < points.size(); ++i)
          if (active_pts_[i] == kActive && stat_pts_[i] > thr) active_pts_[i] = kRejected;
        for (std::size_t i = 0; i < lines.size(); ++i)
          if (active_lines_[i] == kActive && stat_lines_[i] > thr) active_lines_[i] = kRejected;
      }
    }
  }

  // 3./4. Remove-largest loop on plain weights, with one re-admission pass.
  const double thr = p_.outlier_threshold * scale;
  bool readmitted = false;
  Matrix6d H_inv;
  for (;;) {
    const SolveStatus st = gauss_newton(T, points, lines, /*robust=*/false, p_.max_iterations, res.iterations,
                                        converged, ne);
    if (st != SolveStatus::kOk) return finish(st);
    if (!detect) break;
    if (!invert_normal(ne.H, p_.degeneracy_ratio, H_inv)) return finish(SolveStatus::kDegenerate);
    statistics(T, H_inv, points, lines, Statistic::kStandardised);

    double worst = 0.0;
    std::uint8_t* worst_state = nullptr;
    const auto consider = [&](std::uint8_t& state, double stat) {
      if (state == kActive && stat > worst) {
        worst = stat;
        worst_state = &state;
      }
    };
    for (std::size_t i = 0; i < points.size(); ++i) consider(active_pts_[i], stat_pts_[i]);
    for (std::size_t i = 0; i < lines.size(); ++i) consider(active_lines_[i], stat_lines_[i]);
    const bool can_remove = res.outlier_rounds < p_.max_outlier_rounds &&
                            count_active() - 1 >= std::max(p_.min_observations, 1) &&
                            ne.residuals - 2 > kUnknowns;
    if (worst > thr && worst_state != nullptr && can_remove) {
      *worst_state = kRejected;
      ++res.outlier_rounds;
      continue;
    }
    if (!readmitted) {
      readmitted = true;
      bool any = false;
      for (std::size_t i = 0; i < points.size(); ++i)
        if (active_pts_[i] == kRejected && stat_pts_[i] <= thr) active_pts_[i] = kActive, any = true;
      for (std::size_t i = 0; i < lines.size(); ++i)
        if (active_lines_[i] == kRejected && stat_lines_[i] <= thr) active_lines_[i] = kActive, any = true;
      if (any) continue;
    }
    break;
  }

  // 5. Accuracy of the final pose.
  if (ne.behind > 0) return finish(SolveStatus::kDiverged);
  if (!invert_normal(ne.H, p_.degeneracy_ratio, H_inv)) return finish(SolveStatus::kDegenerate);
  const int dof = ne.residuals - kUnknowns;
  res.sigma0 = dof > 0 ? std::sqrt(ne.chi2 / dof) : 1.0;
  const double s0 = std::max(res.sigma0, p_.min_sigma0);
  res.covariance = s0 * s0 * H_inv;
  res.rms_px = ne.residuals > 0 ? std::sqrt(ne.sum_sq_px / ne.residuals) : 0.0;
  res.converged = converged;
  res.T_cam_obj = T;
  return finish(SolveStatus::kOk);
}

}  // namespace v4r::estimation
