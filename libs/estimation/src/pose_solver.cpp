// v4r - robust model-based object tracking. MIT licence.
//
// Object-space pose solver after Wunsch (1997), paper section 5. Everything is computed in
// normalised units: each scalar residual is divided by its a-priori object-space sigma, so the
// normal matrix H = sum J^T J and the gradient g = sum J^T r are in units of sigma and the
// sum of squared residuals is chi-square distributed when the a-priori sigmas are right.
//
// Observation types and their scalar residuals (m): 2-D point (2), line (2), circle edge point
// (1), 3-D point (3), surface normal (2). All live in one array of "slots" (points first, then
// lines, circles, 3-D points, normals) so that the adjustment and the outlier logic treat them
// alike. An observation's test statistic is its chi-square value t (m dof) mapped to the common
// scale s = sqrt(-ln P(chi2_m > t)), the RMS of a 2-residual observation with the same tail
// probability (s = sqrt(t / 2) for m = 2, the original per-observation RMS).
//
// Every Gauss-Newton step is checked: it must not increase the objective it minimised (the
// point and line weights, which depend on depth, frozen at the step's start as in Wunsch's
// method; circle residuals carry their pose-dependent weight in the Jacobian), else it is halved.
// Points and lines rarely need this; circle edge points far from the solution do.
//
// Solve flow:
//   1. prepare: reject invalid input (non-finite, sigma <= 0, coincident line points, zero
//      normals, radius <= 0), cache the line-of-sight bases of the points, the interpretation-
//      plane normals of the lines, unit circle axes and the bases around measured normals.
//   2. robust pass (optional): Gauss-Newton with Cauchy IRLS weights from T_init; the scale is
//      re-estimated every iteration from a low quantile of the residuals (never below the
//      a-priori sigma).
//      Observations whose residual at the robust pose exceeds the threshold are rejected.
//   3. remove-largest loop (Kraus): plain weighted least squares; the active observation with
//      the largest standardised residual (residual over its own standard deviation in the fit,
//      using the redundancy I - J H^-1 J^T) is removed while it exceeds the threshold.
//   4. once, rejected observations that agree with the final pose (predicted residual within the
//      threshold) are re-admitted and step 3 is repeated.
//   5. covariance max(sigma0, min_sigma0)^2 * H^-1, rms in pixels, inlier flags; without a
//      prior also the sandwich covariance, each inlier's spread from its own residual.

#include "v4r/estimation/pose_solver.hpp"

#include "v4r/geometry/se3_jacobians.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

namespace v4r::estimation {

namespace {

using geometry::Matrix6d;
using geometry::SE3;
using geometry::Vector6d;

constexpr std::uint8_t kRejected = 0;
constexpr std::uint8_t kActive = 1;
constexpr std::uint8_t kInvalid = 2;
constexpr int kUnknowns = 6;
/// Statistic of an observation that cannot be evaluated at the current pose (circle ray missing
/// the plane, flipped normal): a gross error.
constexpr double kUnusableStat = 1e6;
/// Quantile of the per-observation residuals from which the noise scale is estimated. A low
/// quantile keeps the estimate meaningful with up to ~(1 - kScaleQuantile) gross errors (the
/// median breaks down at 50 %).
constexpr double kScaleQuantile = 0.3;
/// Relative standard error of the sample quantile p of the RMS Y of two unit Gaussian residuals
/// (P(Y <= y) = 1 - exp(-y^2)) from n values, times sqrt(n): sqrt(p / (1 - p)) / (2 (-ln(1 - p))).
/// Used for every mix of types (the mapped statistics all follow Y's law under the null).
const double kScaleRelError =
    std::sqrt(kScaleQuantile / (1.0 - kScaleQuantile)) / (-2.0 * std::log1p(-kScaleQuantile));
/// Standard errors below the estimate at which the adaptive threshold's scale is taken.
constexpr double kScaleConfidence = 3.0;
/// Regularisation of the residual cofactor matrix of an observation (units of sigma^2).
constexpr double kCofactorEps = 1e-6;
/// A Gauss-Newton step is rejected (halved) when it makes its objective grow by more than this
/// (relative and absolute, units of sigma^2): rounding only.
constexpr double kCostTolerance = 1e-10;
/// Most halvings of a step that increases the objective.
constexpr int kMaxStepHalvings = 10;
/// A full step (m / rad) below which a direction without descent counts as converged.
constexpr double kStallStep = 1e-6;

/// -ln P(chi2_m > t) for m = 1, 2, 3 (t >= 0): closed forms via erfc, asymptotic expansions
/// where erfc underflows.
double chi2_log_survival(double t, int m) {
  if (!(t > 0.0)) return 0.0;
  constexpr double kSqrtPi = 1.7724538509055160273;
  constexpr double kSqrt2OverPi = 0.79788456080286535588;
  switch (m) {
    case 1: {
      const double z = std::sqrt(0.5 * t);
      if (z < 20.0) return -std::log(std::erfc(z));
      const double iz2 = 1.0 / (z * z);  // erfc(z) ~ exp(-z^2) / (z sqrt(pi)) (1 - 1/(2z^2) + 3/(4z^4))
      return z * z + std::log(z * kSqrtPi) - std::log1p(-0.5 * iz2 + 0.75 * iz2 * iz2);
    }
    case 3: {
      const double x = std::sqrt(t);
      if (x < 30.0) return -std::log(std::erfc(x / std::sqrt(2.0)) + kSqrt2OverPi * x * std::exp(-0.5 * t));
      return 0.5 * t - std::log(kSqrt2OverPi * (x + 1.0 / x));  // Q ~ sqrt(2/pi) exp(-x^2/2) (x + 1/x)
    }
    default:
      return 0.5 * t;
  }
}

/// Quantile p of chi2 with m dof: solves -ln P(chi2_m > t) = -ln(1 - p) by bisection.
double chi2_quantile(int m, double p) {
  const double target = -std::log1p(-p);
  double lo = 0.0, hi = 100.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (chi2_log_survival(mid, m) < target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

/// kScaleQuantile-quantiles of chi2 with 0 (unused), 1, 2, 3 dof.
const std::array<double, 4> kChi2AtScaleQuantile = {1.0, chi2_quantile(1, kScaleQuantile),
                                                    chi2_quantile(2, kScaleQuantile),
                                                    chi2_quantile(3, kScaleQuantile)};

bool finite(const Eigen::Vector2d& v) { return v.allFinite(); }
bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }
bool positive(double s) { return std::isfinite(s) && s > 0.0; }

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

void PoseSolver::reserve(std::size_t points, std::size_t lines, std::size_t circles, std::size_t points3d,
                         std::size_t normals) {
  const std::size_t n = points + lines + circles + points3d + normals;
  active_.reserve(n);
  dims_.reserve(n);
  rho_.reserve(n);
  chi2_.reserve(n);
  scratch_.reserve(n);
  depth_ref_.reserve(n);
  depth_trial_.reserve(n);
  point_bases_.reserve(points);
  line_normals_.reserve(lines);
  circle_axes_.reserve(circles);
  normal_bases_.reserve(normals);
  normal_objs_.reserve(normals);
}

void PoseSolver::prepare(const ObservationSet& obs) {
  multi_camera_ = !obs.cameras.empty();
  // Observations of a camera the set does not give (or of one beyond kMaxSolveCameras) are invalid.
  const std::size_t n_cams = multi_camera_ ? std::min(obs.cameras.size(), kMaxSolveCameras) : 1;
  const auto camera_ok = [&](std::uint8_t c) { return c < n_cams; };
  end_points_ = obs.points.size();
  end_lines_ = end_points_ + obs.lines.size();
  end_circles_ = end_lines_ + obs.circles.size();
  end_points3d_ = end_circles_ + obs.points3d.size();
  end_normals_ = end_points3d_ + obs.normals.size();
  const std::size_t n = end_normals_;
  active_.resize(n);
  dims_.assign(n, 0);
  rho_.assign(n, 1.0);
  chi2_.assign(n, 0.0);
  scratch_.resize(n);
  depth_ref_.assign(n, Eigen::Vector2d::Ones());
  depth_trial_.assign(n, Eigen::Vector2d::Ones());
  point_bases_.resize(obs.points.size());
  line_normals_.resize(obs.lines.size());
  circle_axes_.resize(obs.circles.size());
  normal_bases_.resize(obs.normals.size());
  normal_objs_.resize(obs.normals.size());

  std::size_t s = 0;
  for (std::size_t i = 0; i < obs.points.size(); ++i, ++s) {
    const PointObservation& o = obs.points[i];
    const bool ok = finite(o.X_obj) && finite(o.xn) && positive(o.sigma_px) && camera_ok(o.camera);
    active_[s] = ok ? kActive : kInvalid;
    if (ok) point_bases_[i] = ray_basis(o.xn);
  }
  for (std::size_t i = 0; i < obs.lines.size(); ++i, ++s) {
    const LineObservation& o = obs.lines[i];
    bool ok = finite(o.X1_obj) && finite(o.X2_obj) && finite(o.xn1) && finite(o.xn2) && positive(o.sigma_px) &&
              camera_ok(o.camera);
    if (ok) {
      line_normals_[i] = interpretation_plane_normal(o.xn1, o.xn2);
      ok = line_normals_[i].squaredNorm() > 0.5;
    }
    active_[s] = ok ? kActive : kInvalid;
  }
  for (std::size_t i = 0; i < obs.circles.size(); ++i, ++s) {
    const CircleObservation& o = obs.circles[i];
    const double len = o.normal_obj.norm();
    const bool ok = finite(o.center_obj) && finite(o.normal_obj) && finite(o.xn) && positive(o.radius) &&
                    positive(o.sigma_px) && len > 1e-12 && camera_ok(o.camera);
    active_[s] = ok ? kActive : kInvalid;
    if (ok) circle_axes_[i] = o.normal_obj / len;
  }
  for (std::size_t i = 0; i < obs.points3d.size(); ++i, ++s) {
    const Point3Observation& o = obs.points3d[i];
    active_[s] = finite(o.X_obj) && finite(o.P_cam) && positive(o.sigma_m) && camera_ok(o.camera) ? kActive : kInvalid;
  }
  for (std::size_t i = 0; i < obs.normals.size(); ++i, ++s) {
    const NormalObservation& o = obs.normals[i];
    const double lo = o.n_obj.norm(), lc = o.n_cam.norm();
    const bool ok = finite(o.n_obj) && finite(o.n_cam) && positive(o.sigma_rad) && lo > 1e-12 && lc > 1e-12 &&
                    std::isfinite(lo) && std::isfinite(lc) && camera_ok(o.camera);
    active_[s] = ok ? kActive : kInvalid;
    if (ok) {
      normal_objs_[i] = o.n_obj / lo;
      normal_bases_[i] = direction_basis(o.n_cam);
    }
  }
}

void PoseSolver::locate(std::size_t slot, Kind& kind, std::size_t& index) const {
  if (slot < end_points_) {
    kind = Kind::kPoint;
    index = slot;
  } else if (slot < end_lines_) {
    kind = Kind::kLine;
    index = slot - end_points_;
  } else if (slot < end_circles_) {
    kind = Kind::kCircle;
    index = slot - end_lines_;
  } else if (slot < end_points3d_) {
    kind = Kind::kPoint3;
    index = slot - end_circles_;
  } else {
    kind = Kind::kNormal;
    index = slot - end_points3d_;
  }
}

void PoseSolver::pose_cameras(const SE3& T, const ObservationSet& obs) {
  const Eigen::Matrix3d R = T.rotation();
  if (!multi_camera_) {
    cams_[0].R = R;
    cams_[0].t = T.translation();
    cams_[0].w = weighting(p_);
    return;
  }
  for (std::size_t c = 0; c < obs.cameras.size(); ++c) {
    const SolveCamera& sc = obs.cameras[c];
    CameraPose& C = cams_[c];
    const Eigen::Matrix3d Rc = sc.T_cam_ref.rotation();
    C.R = Rc * R;
    C.t = Rc * T.translation() + sc.T_cam_ref.translation();
    C.Ad = geometry::adjoint(sc.T_cam_ref);
    C.w = weighting(p_);
    if (sc.focal_px > 0.0) C.w.focal_px = sc.focal_px;
  }
}

void PoseSolver::evaluate(const ObservationSet& obs, std::size_t slot, bool jacobian, Eval& e) const {
  Kind kind;
  std::size_t i;
  locate(slot, kind, i);
  e.rw.setZero();
  if (jacobian) e.Jw.setZero();
  e.m = 0;
  e.depth.setOnes();
  // Each observation sees the pose through its camera; a Jacobian in that camera's coordinates
  // becomes one of the solved pose's left update by Ad(T_cam_ref).
  std::uint8_t cam = 0;
  switch (kind) {
    case Kind::kPoint: {
      const PointObservation& o = obs.points[i];
      cam = o.camera;
      const CameraPose& C = cams_[o.camera];
      const ResidualWeighting& w = C.w;
      const Eigen::Matrix3d& R = C.R;
      const Eigen::Vector3d& t = C.t;
      Eigen::Vector2d rw;
      Matrix26d J;
      const Eigen::Vector3d p = R * o.X_obj + t;
      normalised_point_residual(p, point_bases_[i], o.sigma_px, w, rw, jacobian ? &J : nullptr);
      e.depth = Eigen::Vector2d::Constant(std::max(p.z(), w.min_depth));
      e.rw.head<2>() = rw;
      if (jacobian) e.Jw.topRows<2>() = J;
      e.m = 2;
      break;
    }
    case Kind::kLine: {
      const LineObservation& o = obs.lines[i];
      cam = o.camera;
      const CameraPose& C = cams_[o.camera];
      const ResidualWeighting& w = C.w;
      const Eigen::Matrix3d& R = C.R;
      const Eigen::Vector3d& t = C.t;
      Eigen::Vector2d rw;
      Matrix26d J;
      const Eigen::Vector3d p1 = R * o.X1_obj + t, p2 = R * o.X2_obj + t;
      normalised_line_residual(p1, p2, line_normals_[i], o.sigma_px, w, rw, jacobian ? &J : nullptr);
      e.depth = Eigen::Vector2d(std::max(p1.z(), w.min_depth), std::max(p2.z(), w.min_depth));
      e.rw.head<2>() = rw;
      if (jacobian) e.Jw.topRows<2>() = J;
      e.m = 2;
      break;
    }
    case Kind::kCircle: {
      const CircleObservation& o = obs.circles[i];
      cam = o.camera;
      const CameraPose& C = cams_[o.camera];
      const ResidualWeighting& w = C.w;
      const Eigen::Matrix3d& R = C.R;
      const Eigen::Vector3d& t = C.t;
      double rw = 0.0;
      Matrix16d J;
      if (!normalised_circle_residual(R * o.center_obj + t, R * circle_axes_[i], o.radius, o.xn, o.sigma_px, w, rw,
                                      jacobian ? &J : nullptr))
        return;
      e.rw(0) = rw;
      if (jacobian) e.Jw.row(0) = J;
      e.m = 1;
      break;
    }
    case Kind::kPoint3: {
      const Point3Observation& o = obs.points3d[i];
      cam = o.camera;
      const Eigen::Matrix3d& R = cams_[o.camera].R;
      const Eigen::Vector3d& t = cams_[o.camera].t;
      Eigen::Vector3d rw;
      Matrix36d J;
      normalised_point3_residual(R * o.X_obj + t, o.P_cam, o.sigma_m, rw, jacobian ? &J : nullptr);
      e.rw = rw;
      if (jacobian) e.Jw = J;
      e.m = 3;
      break;
    }
    case Kind::kNormal: {
      const NormalObservation& o = obs.normals[i];
      cam = o.camera;
      const Eigen::Matrix3d& R = cams_[o.camera].R;
      Eigen::Vector2d rw;
      Matrix26d J;
      if (!normalised_normal_residual(R * normal_objs_[i], normal_bases_[i], o.sigma_rad, rw, jacobian ? &J : nullptr))
        return;
      e.rw.head<2>() = rw;
      if (jacobian) e.Jw.topRows<2>() = J;
      e.m = 2;
      break;
    }
  }
  if (jacobian && multi_camera_ && e.m > 0) e.Jw = (e.Jw * cams_[cam].Ad).eval();
}

int PoseSolver::count_active() const {
  return static_cast<int>(std::count(active_.begin(), active_.end(), kActive));
}

int PoseSolver::min_active() const { return has_prior_ ? 1 : std::max(p_.min_observations, 1); }

namespace {

/// H += rho J^T J (upper triangle; mirrored by the caller), g += rho J^T r for M residuals.
template <int M>
[[gnu::always_inline]] inline void accumulate(const Eigen::Matrix<double, M, 1>& rw,
                                              const Eigen::Matrix<double, M, 6>& Jw, double rho, Matrix6d& H,
                                              Vector6d& g) {
  for (int k = 0; k < M; ++k) {
    for (int i = 0; i < 6; ++i) {
      const double a = rho * Jw(k, i);
      g(i) += a * rw(k);
      for (int j = i; j < 6; ++j) H(i, j) += a * Jw(k, j);
    }
  }
}

}  // namespace

PoseSolver::NormalEquations PoseSolver::linearise(const SE3& T, const ObservationSet& obs, bool robust) {
  // One loop per type (fixed-size Jacobians): this is the hot path of every iteration. The
  // point and line weights' depths go to depth_trial_; frozen_chi2 re-weights their residuals
  // with the depths of depth_ref_ (weight ~ 1 / depth).
  NormalEquations ne;
  pose_cameras(T, obs);
  // Jacobian of a left update of T from that of the observation's camera (see evaluate).
  const auto to_ref = [&](auto& J, std::uint8_t cam) {
    if (multi_camera_) J = (J * cams_[cam].Ad).eval();
  };
  const auto rho = [&](std::size_t s) { return robust ? rho_[s] : 1.0; };
  const auto add = [&](std::size_t s, double sq, double frozen_sq, int m, double sigma_px) {
    ne.chi2 += sq;
    ne.weighted_chi2 += rho(s) * sq;
    ne.frozen_chi2 += rho(s) * frozen_sq;
    ne.residuals += m;
    if (sigma_px > 0.0) {
      ne.sum_sq_px += sq * sigma_px * sigma_px;
      ne.image_residuals += m;
    }
  };
  Eigen::Vector2d rw2;
  Matrix26d J2;
  std::size_t s = 0;
  for (std::size_t i = 0; i < obs.points.size(); ++i, ++s) {
    if (active_[s] != kActive) continue;
    const PointObservation& o = obs.points[i];
    const CameraPose& C = cams_[o.camera];
    const ResidualWeighting& w = C.w;
    const Eigen::Vector3d p = C.R * o.X_obj + C.t;
    ne.behind += normalised_point_residual(p, point_bases_[i], o.sigma_px, w, rw2, &J2) ? 1 : 0;
    to_ref(J2, o.camera);
    accumulate<2>(rw2, J2, rho(s), ne.H, ne.g);
    const double z = std::max(p.z(), w.min_depth), f = z / depth_ref_[s].x();
    depth_trial_[s].setConstant(z);
    add(s, rw2.squaredNorm(), rw2.squaredNorm() * f * f, 2, o.sigma_px);
  }
  for (std::size_t i = 0; i < obs.lines.size(); ++i, ++s) {
    if (active_[s] != kActive) continue;
    const LineObservation& o = obs.lines[i];
    const CameraPose& C = cams_[o.camera];
    const ResidualWeighting& w = C.w;
    const Eigen::Vector3d p1 = C.R * o.X1_obj + C.t, p2 = C.R * o.X2_obj + C.t;
    ne.behind += normalised_line_residual(p1, p2, line_normals_[i], o.sigma_px, w, rw2, &J2) ? 1 : 0;
    to_ref(J2, o.camera);
    accumulate<2>(rw2, J2, rho(s), ne.H, ne.g);
    const Eigen::Vector2d z(std::max(p1.z(), w.min_depth), std::max(p2.z(), w.min_depth));
    const Eigen::Vector2d frozen = rw2.cwiseProduct(z).cwiseQuotient(depth_ref_[s]);
    depth_trial_[s] = z;
    add(s, rw2.squaredNorm(), frozen.squaredNorm(), 2, o.sigma_px);
  }
  for (std::size_t i = 0; i < obs.circles.size(); ++i, ++s) {
    if (active_[s] != kActive) continue;
    const CircleObservation& o = obs.circles[i];
    const CameraPose& C = cams_[o.camera];
    Eigen::Matrix<double, 1, 1> rw1;
    Matrix16d J1;
    if (!normalised_circle_residual(C.R * o.center_obj + C.t, C.R * circle_axes_[i], o.radius, o.xn, o.sigma_px, C.w,
                                    rw1(0), &J1)) {
      ++ne.unusable;
      continue;
    }
    to_ref(J1, o.camera);
    accumulate<1>(rw1, J1, rho(s), ne.H, ne.g);
    add(s, rw1(0) * rw1(0), rw1(0) * rw1(0), 1, o.sigma_px);  // exact Jacobian: nothing frozen
  }
  for (std::size_t i = 0; i < obs.points3d.size(); ++i, ++s) {
    if (active_[s] != kActive) continue;
    const Point3Observation& o = obs.points3d[i];
    Eigen::Vector3d rw3;
    Matrix36d J3;
    normalised_point3_residual(cams_[o.camera].R * o.X_obj + cams_[o.camera].t, o.P_cam, o.sigma_m, rw3, &J3);
    to_ref(J3, o.camera);
    accumulate<3>(rw3, J3, rho(s), ne.H, ne.g);
    add(s, rw3.squaredNorm(), rw3.squaredNorm(), 3, 0.0);
  }
  for (std::size_t i = 0; i < obs.normals.size(); ++i, ++s) {
    if (active_[s] != kActive) continue;
    const NormalObservation& o = obs.normals[i];
    if (!normalised_normal_residual(cams_[o.camera].R * normal_objs_[i], normal_bases_[i], o.sigma_rad, rw2, &J2)) {
      ++ne.unusable;
      continue;
    }
    to_ref(J2, o.camera);
    accumulate<2>(rw2, J2, rho(s), ne.H, ne.g);
    add(s, rw2.squaredNorm(), rw2.squaredNorm(), 2, 0.0);
  }
  if (has_prior_) {
    // r = log(T Tp^-1); for a left update exp(d) T, r(d) ~ d + r: the Jacobian is U.
    const Vector6d rw = prior_U_ * (T * prior_T_.inverse()).log();
    ne.H.noalias() += prior_U_.transpose() * prior_U_;
    ne.g.noalias() += prior_U_.transpose() * rw;
    const double sq = rw.squaredNorm();
    ne.chi2 += sq;
    ne.weighted_chi2 += sq;
    ne.frozen_chi2 += sq;
    ne.residuals += kUnknowns;
  }
  ne.H.triangularView<Eigen::StrictlyLower>() = ne.H.transpose();
  return ne;
}

double PoseSolver::statistics(const SE3& T, const Matrix6d& H_inv, const ObservationSet& obs, Statistic kind) {
  pose_cameras(T, obs);
  const bool standardised = kind == Statistic::kStandardised;
  double frozen_cost = 0.0;
  Eval e;
  for (std::size_t s = 0; s < active_.size(); ++s) {
    if (active_[s] == kInvalid) continue;
    evaluate(obs, s, standardised, e);
    dims_[s] = static_cast<std::uint8_t>(e.m);
    if (e.m == 0) {
      chi2_[s] = 0.0;
      if (active_[s] == kActive) frozen_cost += kUnusableStat * kUnusableStat;
      continue;
    }
    if (!standardised) {
      chi2_[s] = e.rw.squaredNorm();
      if (active_[s] == kActive) {
        // Point / line weights ~ 1 / depth: back to the reference depths (others: 1).
        const Eigen::Vector2d f = e.depth.cwiseQuotient(depth_ref_[s]);
        const double frozen = e.m == 2 && s < end_lines_ ? Eigen::Vector2d(e.rw.head<2>().cwiseProduct(f)).squaredNorm()
                                                         : chi2_[s];
        frozen_cost += rho_[s] * frozen;
      }
      continue;
    }
    // Cofactor of the residual: I - J H^-1 J^T for an observation in the fit (its redundancy),
    // I + J H^-1 J^T for one left out (prediction error of the pose adds to its own noise). Rows
    // beyond m are zero in J and r, so the padded 3x3 form gives the m x m result.
    const Eigen::Matrix3d M = e.Jw * H_inv * e.Jw.transpose();
    Eigen::Matrix3d Q = active_[s] == kActive ? Eigen::Matrix3d(Eigen::Matrix3d::Identity() - M)
                                              : Eigen::Matrix3d(Eigen::Matrix3d::Identity() + M);
    Q.diagonal().array() += kCofactorEps;
    chi2_[s] = std::max(e.rw.dot(Q.inverse() * e.rw), 0.0);
  }
  if (has_prior_ && !standardised) frozen_cost += (prior_U_ * (T * prior_T_.inverse()).log()).squaredNorm();
  return frozen_cost;
}

double PoseSolver::stat(std::size_t slot, double scale) const {
  const int m = dims_[slot];
  if (m == 0) return kUnusableStat;
  return std::sqrt(chi2_log_survival(chi2_[slot] / (scale * scale), m));
}

double PoseSolver::quantile_scale() {
  // sqrt(t / q_m) with q_m the kScaleQuantile-quantile of chi2_m: at unit noise every active
  // observation falls below 1 with probability kScaleQuantile, so the quantile of these values
  // estimates the noise scale for any mix of types.
  std::size_t n = 0;
  for (std::size_t s = 0; s < active_.size(); ++s) {
    if (active_[s] != kActive) continue;
    const int m = dims_[s];
    scratch_[n++] = m == 0 ? kUnusableStat : std::sqrt(chi2_[s] / kChi2AtScaleQuantile[static_cast<std::size_t>(m)]);
  }
  if (n == 0) return 1.0;
  const auto q = scratch_.begin() + static_cast<std::ptrdiff_t>(kScaleQuantile * static_cast<double>(n - 1));
  std::nth_element(scratch_.begin(), q, scratch_.begin() + static_cast<std::ptrdiff_t>(n));
  return *q;
}

void PoseSolver::update_robust_weights(double scale) {
  for (std::size_t s = 0; s < active_.size(); ++s) {
    if (active_[s] != kActive) continue;
    const double u = stat(s, scale) / p_.cauchy_c;
    rho_[s] = 1.0 / (1.0 + u * u);
  }
}

SolveStatus PoseSolver::gauss_newton(SE3& T, const ObservationSet& obs, bool robust, int max_iterations,
                                     int& iterations, bool& converged, NormalEquations& last) {
  converged = false;
  const Matrix6d no_inverse = Matrix6d::Zero();
  // Objective of a step: the sum of squared normalised residuals, in the robust pass weighted
  // with the IRLS weights of the step's start, with the point and line weights frozen at the
  // start (the objective the Gauss-Newton step minimises; weights are re-evaluated after it).
  // Observations unusable at a pose count as gross errors, so a step cannot "improve" by making
  // them unusable.
  constexpr double kPenalty = kUnusableStat * kUnusableStat;
  const auto commit = [&]() { depth_ref_.swap(depth_trial_); };
  const auto reweight = [&]() {  // robust: statistics at T are current
    update_robust_weights(std::max(1.0, quantile_scale()));
  };
  if (robust) {
    statistics(T, no_inverse, obs, Statistic::kPlain);
    reweight();
  }
  last = linearise(T, obs, robust);
  commit();
  double cost = last.weighted_chi2 + kPenalty * last.unusable;
  NormalEquations trial;
  for (int it = 0; it < max_iterations; ++it) {
    if (last.residuals < kUnknowns || count_active() < min_active())
      return SolveStatus::kTooFewObservations;
    if (!last.H.allFinite() || !last.g.allFinite()) return SolveStatus::kDiverged;
    Vector6d s;
    if (!balance(last.H, s)) return SolveStatus::kDegenerate;
    const Matrix6d Hb = s.asDiagonal() * last.H * s.asDiagonal();
    const Eigen::LDLT<Matrix6d> ldlt(Hb);
    if (ldlt.info() != Eigen::Success) return SolveStatus::kDegenerate;
    const Vector6d d = ldlt.vectorD().cwiseAbs();
    if (!(d.minCoeff() > p_.degeneracy_ratio * d.maxCoeff())) return SolveStatus::kDegenerate;
    Vector6d delta = -(s.asDiagonal() * ldlt.solve(s.asDiagonal() * last.g)).eval();
    if (!delta.allFinite()) return SolveStatus::kDiverged;
    const double full_step = delta.norm();

    // Step control: halve the Gauss-Newton step while it increases the objective (far from the
    // solution the linearisation can overshoot, e.g. circle edge points of an oblique circle or
    // whose rays meet the plane near the centre). In the plain pass the trial evaluation is the
    // next iteration's linearisation.
    SE3 T_new;
    double cost_new = 0.0;
    bool accepted = false;
    int halvings = 0;
    for (; halvings <= kMaxStepHalvings; ++halvings, delta *= 0.5) {
      T_new = SE3::exp(delta) * T;
      if (robust) {
        cost_new = statistics(T_new, no_inverse, obs, Statistic::kPlain);
      } else {
        trial = linearise(T_new, obs, false);
        cost_new = trial.frozen_chi2 + kPenalty * trial.unusable;
      }
      if (cost_new <= cost * (1.0 + kCostTolerance) + kCostTolerance) {
        accepted = true;
        break;
      }
    }
    if (!accepted) {
      // No descent along the Gauss-Newton direction: a minimum to numerical precision when the
      // step was tiny anyway.
      converged = full_step < kStallStep;
      if (robust) statistics(T, no_inverse, obs, Statistic::kPlain);
      break;
    }
    T = T_new;
    ++iterations;
    if (robust) {
      reweight();
      last = linearise(T, obs, true);
    } else {
      last = trial;
    }
    commit();
    cost = last.weighted_chi2 + kPenalty * last.unusable;
    if (halvings == 0 && full_step < (robust ? p_.robust_step_tolerance : p_.step_tolerance)) {
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
  ObservationSet obs;
  obs.points = points;
  obs.lines = lines;
  InlierFlags flags;
  flags.points = point_inlier;
  flags.lines = line_inlier;
  return solve(T_init, obs, flags);
}

PoseResult PoseSolver::solve(const SE3& T_init, const ObservationSet& obs, const InlierFlags& flags) {
  PoseResult res;
  res.T_cam_obj = T_init;
  prepare(obs);
  has_prior_ = false;
  if (obs.prior != nullptr && obs.prior->information.allFinite() && obs.prior->T_cam_obj.translation().allFinite() &&
      obs.prior->T_cam_obj.quaternion().coeffs().allFinite()) {
    const Eigen::LLT<Matrix6d> llt(0.5 * (obs.prior->information + obs.prior->information.transpose()));
    if (llt.info() == Eigen::Success) {
      prior_U_ = llt.matrixU();
      prior_T_ = obs.prior->T_cam_obj;
      has_prior_ = true;
    }
  }
  res.observations = static_cast<int>(active_.size());

  const auto finish = [&](SolveStatus status) {
    res.status = status;
    res.inliers = count_active();
    const auto write = [&](std::span<std::uint8_t> out, std::size_t begin, std::size_t end) {
      if (out.size() != end - begin) return;
      for (std::size_t s = begin; s < end; ++s) out[s - begin] = active_[s] == kActive ? 1 : 0;
    };
    write(flags.points, 0, end_points_);
    write(flags.lines, end_points_, end_lines_);
    write(flags.circles, end_lines_, end_circles_);
    write(flags.points3d, end_circles_, end_points3d_);
    write(flags.normals, end_points3d_, end_normals_);
    return res;
  };

  if (!T_init.translation().allFinite() || !T_init.quaternion().coeffs().allFinite())
    return finish(SolveStatus::kDiverged);
  if (!(p_.focal_px > 0.0) || !std::isfinite(p_.focal_px)) return finish(SolveStatus::kDegenerate);
  for (const SolveCamera& c : obs.cameras)
    if (!c.T_cam_ref.translation().allFinite() || !c.T_cam_ref.quaternion().coeffs().allFinite() ||
        !std::isfinite(c.focal_px))
      return finish(SolveStatus::kDegenerate);
  if (count_active() < min_active()) return finish(SolveStatus::kTooFewObservations);

  const bool detect = p_.max_outlier_rounds > 0 && p_.outlier_threshold > 0.0;
  const std::size_t n = active_.size();
  SE3 T = T_init;
  NormalEquations ne;
  bool converged = false;
  double scale = 1.0;

  // 2. Robust pass: a starting pose that gross errors have not pulled, and a first inlier set.
  if (detect && p_.robust_init) {
    SE3 T_r = T;
    const SolveStatus st = gauss_newton(T_r, obs, /*robust=*/true, p_.robust_max_iterations, res.iterations,
                                        converged, ne);
    if (st == SolveStatus::kOk) {
      T = T_r;
      statistics(T, Matrix6d::Zero(), obs, Statistic::kPlain);
      // Noise scale from a low quantile of the residuals, corrected for the shrinking of
      // residuals by the fit (redundancy fraction). The threshold only widens when the scale is
      // significantly above 1: its lower 3-standard-error confidence bound is used, so that the
      // noisy estimate from few observations does not cost detection power.
      const int n_active = count_active();
      const double redundancy =
          std::max(1.0 - static_cast<double>(kUnknowns) / std::max(ne.residuals, kUnknowns + 1), 0.1);
      res.noise_scale = quantile_scale() / std::sqrt(redundancy);
      const double lower_bound =
          res.noise_scale / (1.0 + kScaleConfidence * kScaleRelError / std::sqrt(n_active));
      scale = p_.adaptive_threshold ? std::max(1.0, lower_bound) : 1.0;
      const bool scale_plausible = scale <= p_.max_threshold_scale;
      int gross = 0;
      for (std::size_t s = 0; s < n; ++s) gross += active_[s] == kActive && stat(s, scale) > p_.outlier_threshold;
      // A robust fit that disagrees with most observations, or whose residuals are many times
      // the a-priori sigma, was most likely pulled by gross errors (IRLS breaks down well below
      // 50 % contamination when the errors pull coherently): it does not decide, and neither
      // does its scale. The remove-largest loop takes over from T_init with the a-priori
      // threshold (slower, but it copes with higher contamination by large errors).
      if (!scale_plausible || 2 * gross > n_active || n_active - gross < p_.min_observations) {
        T = T_init;
        scale = 1.0;
      } else {
        for (std::size_t s = 0; s < n; ++s)
          if (active_[s] == kActive && stat(s, scale) > p_.outlier_threshold) active_[s] = kRejected;
      }
    }
  }

  // 3./4. Remove-largest loop on plain weights, with one re-admission pass.
  const double thr = p_.outlier_threshold;
  bool readmitted = false;
  Matrix6d H_inv;
  for (;;) {
    const SolveStatus st = gauss_newton(T, obs, /*robust=*/false, p_.max_iterations, res.iterations, converged, ne);
    if (st != SolveStatus::kOk) return finish(st);
    if (!detect) break;
    if (!invert_normal(ne.H, p_.degeneracy_ratio, H_inv)) return finish(SolveStatus::kDegenerate);
    statistics(T, H_inv, obs, Statistic::kStandardised);

    double worst = 0.0;
    std::size_t worst_slot = n;
    for (std::size_t s = 0; s < n; ++s) {
      if (active_[s] != kActive) continue;
      const double v = stat(s, scale);
      if (v > worst) {
        worst = v;
        worst_slot = s;
      }
    }
    const bool can_remove = worst_slot < n && res.outlier_rounds < p_.max_outlier_rounds &&
                            count_active() - 1 >= min_active() &&
                            ne.residuals - dims_[worst_slot] > kUnknowns;
    if (worst > thr && can_remove) {
      active_[worst_slot] = kRejected;
      ++res.outlier_rounds;
      continue;
    }
    if (!readmitted) {
      readmitted = true;
      bool any = false;
      for (std::size_t s = 0; s < n; ++s) {
        if (active_[s] == kRejected && dims_[s] > 0 && stat(s, scale) <= thr) {
          active_[s] = kActive;
          any = true;
        }
      }
      if (any) continue;
    }
    break;
  }

  // 5. Accuracy of the final pose. Observations unusable at it did not enter H: flag them.
  if (ne.behind > 0) return finish(SolveStatus::kDiverged);
  if (ne.unusable > 0) {
    pose_cameras(T, obs);
    Eval e;
    for (std::size_t s = 0; s < n; ++s) {
      if (active_[s] != kActive) continue;
      evaluate(obs, s, /*jacobian=*/false, e);
      if (e.m == 0) active_[s] = kRejected;
    }
    if (ne.residuals < kUnknowns || count_active() < min_active())
      return finish(SolveStatus::kTooFewObservations);
  }
  if (!invert_normal(ne.H, p_.degeneracy_ratio, H_inv)) return finish(SolveStatus::kDegenerate);
  const int dof = ne.residuals - kUnknowns;
  res.sigma0 = dof > 0 ? std::sqrt(ne.chi2 / dof) : 1.0;
  const double s0 = std::max(res.sigma0, p_.min_sigma0);
  res.covariance = s0 * s0 * H_inv;
  if (p_.sandwich && !has_prior_) {
    pose_cameras(T, obs);
    Eval e;
    Matrix6d C = Matrix6d::Zero();
    int count = 0;
    for (std::size_t s = 0; s < n; ++s) {
      if (active_[s] != kActive) continue;
      evaluate(obs, s, /*jacobian=*/true, e);
      if (e.m == 0) continue;
      // The residual's cofactor Q = I - J H^-1 J^T (its covariance in units of sigma^2):
      // Q^-1/2 r has unit covariance for independent errors of the a-priori form.
      Eigen::Matrix3d Q = Eigen::Matrix3d::Identity() - e.Jw * H_inv * e.Jw.transpose();
      Q.diagonal().array() += kCofactorEps;
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> qs(0.5 * (Q + Q.transpose()));
      const Eigen::Vector3d q = qs.eigenvalues().cwiseMax(kCofactorEps);
      const Eigen::Vector3d u = qs.eigenvectors() * (qs.eigenvectors().transpose() * e.rw).cwiseQuotient(q.cwiseSqrt());
      const Vector6d d = H_inv * e.Jw.transpose() * u;
      C.noalias() += d * d.transpose();
      ++count;
    }
    if (count >= 2) res.sandwich_covariance = C;
  }
  res.rms_px = ne.image_residuals > 0 ? std::sqrt(ne.sum_sq_px / ne.image_residuals) : 0.0;
  res.converged = converged;
  res.T_cam_obj = T;
  return finish(SolveStatus::kOk);
}

}  // namespace v4r::estimation
