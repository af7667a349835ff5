// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/object_update.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "v4r/geometry/se3_jacobians.hpp"

namespace v4r::pipeline {

namespace {

/// Information of the covariance a solve reports: its own (ObjectSolve::report_scale), widened
/// to cover the sandwich covariance in every direction where that is larger (their Loewner upper bound
/// C + [J - C]+, the positive part taken over the eigenvalues).
geometry::Matrix6d report_information(const ObjectSolve& s) {
  const geometry::Matrix6d info = s.information / s.report_scale;
  if (!s.sandwich.allFinite() || s.sandwich.trace() <= 0.0) return info;
  const geometry::Matrix6d C = info.inverse();
  const Eigen::SelfAdjointEigenSolver<geometry::Matrix6d> es(0.5 * (s.sandwich - C + (s.sandwich - C).transpose()));
  const geometry::Vector6d ev = es.eigenvalues().cwiseMax(0.0);
  const geometry::Matrix6d W = C + es.eigenvectors() * ev.asDiagonal() * es.eigenvectors().transpose();
  return W.inverse();
}

void track_consistency(scene::Object& obj, const geometry::SE3& T_meas, const geometry::Matrix6d& cov,
                       const CycleParams& p) {
  // The third difference of four consecutive measured poses, a = d_k - 2 d_(k-1) + d_(k-2)
  // with d_k = log(T_k T_(k-1)^-1), is their noise (covariance R_k + 9 R_(k-1) + 9 R_(k-2) +
  // R_(k-3) for independent errors) plus the motion's jerk. Unlike the second difference it
  // passes no constant acceleration: on the benchmark's fast trajectories the second
  // difference of the true poses reaches 0.6 mm, the third about a tenth of that, against a
  // measurement noise of 0.1 .. 0.5 mm.
  if (p.consistency_rate <= 0.0) {
    obj.consistency = 1.0;
    return;
  }
  const int n = obj.consistency_frames;
  if (n >= 3) {
    const geometry::Vector6d d2 = (T_meas * obj.T_meas_prev[0].inverse()).log();
    const geometry::Vector6d d1 = (obj.T_meas_prev[0] * obj.T_meas_prev[1].inverse()).log();
    const geometry::Vector6d d0 = (obj.T_meas_prev[1] * obj.T_meas_prev[2].inverse()).log();
    const geometry::Vector6d a = d2 - 2.0 * d1 + d0;
    const geometry::Matrix6d S = cov + 9.0 * (obj.cov_meas_prev[0] + obj.cov_meas_prev[1]) + obj.cov_meas_prev[2];
    const Eigen::LLT<geometry::Matrix6d> llt(0.5 * (S + S.transpose()));
    if (llt.info() == Eigen::Success && a.allFinite()) {
      const double nis = a.dot(llt.solve(a)) / 6.0;
      if (std::isfinite(nis)) obj.consistency += p.consistency_rate * (std::min(nis, p.consistency_max_scale) - obj.consistency);
    }
  }
  for (int k = 2; k > 0; --k) {
    obj.T_meas_prev[k] = obj.T_meas_prev[k - 1];
    obj.cov_meas_prev[k] = obj.cov_meas_prev[k - 1];
  }
  obj.T_meas_prev[0] = T_meas;
  obj.cov_meas_prev[0] = cov;
  obj.consistency_frames = std::min(n + 1, 3);
}

}  // namespace

ObjectMeasurement combine_solves(std::span<const ObjectSolve> solves) {
  ObjectMeasurement m;
  geometry::SE3 T0;
  geometry::Matrix6d info_sum = geometry::Matrix6d::Zero(), report_info = geometry::Matrix6d::Zero();
  geometry::Vector6d info_xi = geometry::Vector6d::Zero();
  for (const ObjectSolve& s : solves) {
    if (!s.updated) continue;
    if (m.solves == 0) T0 = s.T_ref_obj;
    m.prior_used = m.prior_used || s.prior_used;
    info_sum += s.information;
    report_info += report_information(s);
    info_xi += s.information * (s.T_ref_obj * T0.inverse()).log();
    ++m.solves;
  }
  if (m.solves == 0) return m;
  m.covariance = info_sum.inverse();
  m.reported_covariance = report_info.inverse();
  m.T_ref_obj = m.solves == 1 ? T0 : geometry::SE3::exp(m.covariance * info_xi) * T0;
  return m;
}

void update_object(scene::Object& obj, const ObjectMeasurement& m, const CycleParams& p, ObjectReport& rep,
                   double stamp_s) {
  const bool was_lost = obj.status == scene::TrackStatus::kLost;
  const double frame_dt = obj.last_stamp >= 0.0 && stamp_s > obj.last_stamp ? stamp_s - obj.last_stamp : p.frame_interval_s;
  obj.last_stamp = stamp_s;  // (the filter's time update for this frame was done in process())
  // Status from the image: the share of the projected model's edge samples that the image
  // confirms, at the views' measured poses.
  int ev_samples = 0, ev_matched = 0;
  for (const scene::View& view : obj.views) {
    ev_samples += view.evidence_samples;
    ev_matched += view.evidence_matched;
  }
  const double evidence = ev_samples > 0 ? static_cast<double>(ev_matched) / ev_samples : 0.0;
  rep.evidence = evidence;
  rep.evidence_samples = ev_samples;
  obj.evidence = evidence;
  int leak_samples = 0, leak_matched = 0;
  for (const scene::View& view : obj.views) {
    leak_samples += view.leak_samples;
    leak_matched += view.leak_matched;
  }
  obj.leak = leak_samples > 0 ? static_cast<double>(leak_matched) / leak_samples : -1.0;
  obj.leak_samples = leak_samples;
  // Whether the measurement is used follows the features: the share of visible features used,
  // lowered by large residuals.
  double ratio = rep.features_visible > 0 ? static_cast<double>(rep.lines_used + rep.junctions_used / 2 +
                                                                 (rep.circle_points_used > 0 ? 1 : 0)) /
                                                rep.features_visible
                                          : 0.0;
  ratio = std::clamp(ratio, 0.0, 1.0);
  const double residual_factor = 1.0 / (1.0 + (rep.rms_px / 1.5) * (rep.rms_px / 1.5));
  bool accept = m.solves > 0 && ratio * residual_factor >= p.recovery.lost_quality;
  const geometry::SE3& T_meas = m.T_ref_obj;
  const geometry::Matrix6d& cov_meas = m.covariance;
  const bool prior_used = m.prior_used;
  bool jumped = false;  // the measurement is far from the prediction
  if (p.use_filter) {
    if (accept) {
      // A floor on the measurement covariance keeps the filter from trusting a pose more than the
      // renderer-free reality of a camera allows (0.1 mm, 0.02 degrees).
      geometry::Matrix6d floor = geometry::Matrix6d::Zero();
      floor.diagonal() << 1e-8, 1e-8, 1e-8, 1e-7, 1e-7, 1e-7;
      const double chi2 = obj.filter.innovation_chi2(T_meas, cov_meas + floor);
      jumped = p.recovery.jump_chi2 > 0.0 && chi2 > p.recovery.jump_chi2;
      if (ratio < p.degraded_ratio && chi2 > p.recovery.gate_chi2) {
        accept = false;  // a weak measurement far from the prediction: more likely wrong than right
        rep.measurement_rejected = true;
      } else {
        obj.filter.update(T_meas, cov_meas + floor);
        // The reported pose: the smoother's. At rest (the tracking filter's velocity is
        // insignificant) it holds its velocity at zero and averages the measurements; a moving
        // object is reported where it is measured (the smoother restarts there: no lag), and so
        // is a measurement the smoother cannot explain even at full noise (a recovery, a jump).
        if (p.smooth_output) {
          const bool at_rest = obj.filter.velocity_chi2() <= p.rest_velocity_chi2;
          if (at_rest) obj.smoother.hold_still(p.rest_velocity_sigma, p.rest_angular_velocity_sigma);
          if (!at_rest || obj.smoother.update(T_meas, cov_meas + floor) > p.recovery.gate_chi2)
            obj.smoother.reset(T_meas, cov_meas + floor);
        }
      }
    }
  }
  if (accept) {
    obj.T_ref_obj = p.use_filter && p.smooth_output && obj.smoother.initialised() ? obj.smoother.pose() : T_meas;
    // Directions held by the prediction carry the filter's covariance, not the (huge) one of
    // the observations alone.
    obj.covariance = prior_used && p.use_filter ? obj.filter.pose_covariance() : m.reported_covariance;
    if (!prior_used && !jumped) {
      track_consistency(obj, T_meas, m.reported_covariance, p);
      obj.covariance *= std::max(1.0, obj.consistency);
    } else {
      obj.consistency_frames = 0;
    }
    // The image shows the object image_delay_s before the stamp: reported at the stamp, moved on
    // with the filter's velocity; the covariance grows as if that velocity came from the last two
    // measurements, (R_k + R_k-1) / dt^2 with R_k-1 about R_k. (The filter's own velocity
    // covariance, from its process noise of 2 m/s^2, put the true error at a tenth of a sigma.)
    if (p.use_filter && p.image_delay_s > 0.0 && obj.filter.initialised()) {
      const double d = p.image_delay_s;
      obj.T_ref_obj = geometry::SE3::exp(obj.filter.velocity() * d) * obj.T_ref_obj;
      obj.covariance *= 1.0 + 2.0 * (d / frame_dt) * (d / frame_dt);
    }
    obj.measured = ratio >= p.degraded_ratio && !prior_used ? scene::TrackStatus::kTracking : scene::TrackStatus::kDegraded;
    rep.prior_used = prior_used;
  } else {
    obj.consistency_frames = 0;
    // No usable measurement: hold the prediction (the filter's, which does not run away: its
    // velocity is dropped after a few bad frames) and search wider next time.
    obj.T_ref_obj = obj.T_pred;
    obj.measured = scene::TrackStatus::kLost;
  }
  // The reported status: what the image shows at the pose.
  // Lost by this frame alone (the search starts after search.lost_frames of these); once lost,
  // the status stays lost until the image confirms status.return_evidence again.
  obj.lost_by_image = !accept || evidence < p.status.lost_evidence;
  if (obj.lost_by_image || (was_lost && evidence < p.status.return_evidence)) {
    obj.status = scene::TrackStatus::kLost;
  } else if (evidence >= p.status.tracking_evidence && obj.measured == scene::TrackStatus::kTracking && !jumped) {
    obj.status = scene::TrackStatus::kTracking;
  } else {
    obj.status = scene::TrackStatus::kDegraded;
  }
  obj.quality = accept ? evidence * residual_factor : 0.0;
  // A pose the image does not support carries the prediction's covariance (the filter's, this
  // frame's time update), which grows with time while nothing is measured; never the last
  // measurement's. (covariance_pred is zero without a running filter.)
  if (obj.status == scene::TrackStatus::kLost && obj.covariance_pred.trace() > 0.0) obj.covariance = obj.covariance_pred;
  obj.bad_frames = obj.measured == scene::TrackStatus::kTracking ? 0 : obj.bad_frames + 1;
  obj.confirmed = obj.confirmed || obj.measured == scene::TrackStatus::kTracking;
  if (p.use_filter) {
    if (!accept && obj.bad_frames >= p.recovery.reset_velocity_after) {
      obj.filter.reset_velocity();
      obj.smoother.reset_velocity();
    }
    obj.T_ref_obj_filtered = obj.filter.pose();
    obj.velocity = obj.filter.velocity();
  } else {
    obj.T_ref_obj_filtered = obj.T_ref_obj;
    obj.velocity.setZero();
  }
  if (obj.status == scene::TrackStatus::kTracking) {  // where and how the image last supported it
    obj.T_ref_obj_tracked = obj.T_ref_obj;
    obj.velocity_tracked = obj.velocity;
    obj.stamp_tracked = stamp_s;
    obj.tracked_once = true;
    if (obj.leak >= 0.0 && evidence >= p.status.leak_learn_evidence)
      obj.leak_typical = obj.leak_typical < 0.0 ? obj.leak : obj.leak_typical + p.status.leak_rate * (obj.leak - obj.leak_typical);
  }
  rep.status = obj.status;
  rep.quality = obj.quality;
}

}  // namespace v4r::pipeline
