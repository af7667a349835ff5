// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/object_solver.hpp"

#include <algorithm>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

namespace v4r::pipeline {

ObjectSolve ObjectSolver::solve(const geometry::SE3& T_init, ObservationBuffer& buf, const SolvePrior& prior) {
  ObjectSolve out;
  buf.reset_inliers();
  const int n_obs = buf.independent_count();  // junctions add nothing the lines do not fix
  const bool can_prior = p_.prior_fallback && prior.usable && prior.covariance.allFinite() && prior.covariance.trace() > 0.0;
  if (buf.cameras.empty() || !(n_obs >= p_.min_lines || (can_prior && n_obs >= 1))) return out;

  solver_.params() = p_.solver;
  solver_.params().focal_px = buf.cameras.front().focal_px;
  solver_.params().sandwich = p_.report_sandwich;
  estimation::ObservationSet obs;
  obs.points = buf.points;
  obs.lines = buf.lines;
  obs.circles = buf.circles;
  // One camera at the reference: the plain single-camera solve (the same numbers, less work).
  const bool single = buf.cameras.size() == 1 && buf.cameras.front().T_cam_ref.translation().squaredNorm() == 0.0 &&
                      buf.cameras.front().T_cam_ref.quaternion().w() == 1.0;
  if (!single) obs.cameras = buf.cameras;
  estimation::InlierFlags flags;
  flags.points = buf.point_inliers;
  flags.lines = buf.line_inliers;
  flags.circles = buf.circle_inliers;

  // A solve whose residuals are far above the a-priori noise holds a wrong feature that its few
  // observations cannot single out; the prior's redundancy can.
  estimation::PoseResult result;
  if (n_obs >= p_.min_lines) result = solver_.solve(T_init, obs, flags);
  bool with_prior = false;
  if (can_prior && !(result.ok() && buf.independent_inliers() >= p_.min_lines && result.rms_px <= p_.prior_max_rms_px)) {
    // Partial observability: the image fixes some directions, the prediction the others.
    geometry::Matrix6d cov = prior.covariance;
    cov.diagonal().array() += 1e-12;
    prior_.T_cam_obj = prior.T_ref_obj;
    prior_.information = cov.inverse();
    obs.prior = &prior_;
    buf.reset_inliers();
    result = solver_.solve(prior.T_ref_obj, obs, flags);
    with_prior = result.ok();
  }
  out.result = result;
  if (!result.ok() || !(with_prior || buf.independent_inliers() >= p_.min_lines)) return out;
  out.updated = true;
  out.prior_used = with_prior;
  out.T_ref_obj = result.T_cam_obj;
  // Information of the observations alone: the solve's, less the prior's (both scaled by the
  // solve's sigma0^2), kept positive semi-definite.
  const double s0 = std::max(result.sigma0, p_.solver.min_sigma0);
  geometry::Matrix6d info = result.covariance.inverse();
  if (with_prior) info -= prior_.information / (s0 * s0);
  info = 0.5 * (info + info.transpose()).eval();
  const Eigen::SelfAdjointEigenSolver<geometry::Matrix6d> es(info);
  const geometry::Vector6d ev = es.eigenvalues().cwiseMax(1e-9 * std::max(es.eigenvalues().maxCoeff(), 1e-30));
  out.information = es.eigenvectors() * ev.asDiagonal() * es.eigenvectors().transpose();
  const double s_report = std::max(result.sigma0, p_.report_min_sigma0);
  out.report_scale = (s_report * s_report) / (s0 * s0);
  if (p_.report_sandwich && !with_prior) out.sandwich = result.sandwich_covariance;
  return out;
}

}  // namespace v4r::pipeline
