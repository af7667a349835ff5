// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/vision_cycle.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

#include "v4r/core/clock.hpp"

namespace v4r::pipeline {

namespace {

features::LineTrackerParams search_params(const CycleParams& p) {
  features::LineTrackerParams s = p.track;
  s.half_width = p.search_half_width;
  return s;
}

/// Adjoint of T for tangents ordered (v, w) with left updates: exp(Ad(T) x) * T == T * exp(x).
geometry::Matrix6d adjoint(const geometry::SE3& T) {
  geometry::Matrix6d A = geometry::Matrix6d::Zero();
  const Eigen::Matrix3d R = T.rotation();
  A.topLeftCorner<3, 3>() = R;
  A.topRightCorner<3, 3>() = geometry::hat(T.translation()) * R;
  A.bottomRightCorner<3, 3>() = R;
  return A;
}

/// The measured line in normalised undistorted coordinates. Under lens distortion a straight edge
/// is curved in the image, so the edge pixels are undistorted one by one and a line is fitted to
/// them (total least squares); its ends are the undistorted window ends projected onto it.
void undistorted_line(const geometry::PinholeCamera& K, const features::LineMeasurement& m,
                      const std::vector<Eigen::Vector2d>& edgels, std::vector<Eigen::Vector2d>& buffer,
                      Eigen::Vector2d& n1, Eigen::Vector2d& n2) {
  n1 = K.pixel_to_normalized(m.line.a);
  n2 = K.pixel_to_normalized(m.line.b);
  if (!K.has_distortion() || edgels.size() < 3 || edgels.size() > buffer.capacity()) return;
  buffer.clear();
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& e : edgels) {
    buffer.push_back(K.pixel_to_normalized(e));
    c += buffer.back();
  }
  c /= static_cast<double>(buffer.size());
  Eigen::Matrix2d S = Eigen::Matrix2d::Zero();
  for (const Eigen::Vector2d& q : buffer) S += (q - c) * (q - c).transpose();
  // Principal direction of the 2x2 scatter matrix.
  const double theta = 0.5 * std::atan2(2.0 * S(0, 1), S(0, 0) - S(1, 1));
  Eigen::Vector2d dir(std::cos(theta), std::sin(theta));
  if (dir.dot(n2 - n1) < 0) dir = -dir;
  n1 = c + dir * dir.dot(n1 - c);
  n2 = c + dir * dir.dot(n2 - c);
}

}  // namespace

VisionCycle::VisionCycle(const CycleParams& params)
    : p_(params), tracker_(params.track), searcher_(search_params(params)), solver_(params.solver),
      visibility_(params.visibility) {}

const std::vector<Eigen::Vector2d>& VisionCycle::edgels(std::size_t camera) const {
  static const std::vector<Eigen::Vector2d> kEmpty;
  return camera < edgels_.size() ? edgels_[camera] : kEmpty;
}

void VisionCycle::prepare(const scene::Scene& scene) {
  std::size_t max_lines = 0;
  for (const scene::Object& o : scene.objects()) max_lines = std::max(max_lines, o.model->lines().size());
  if (edge_vis_.size() < max_lines) edge_vis_.resize(max_lines);
  if (line_obs_.capacity() < max_lines) {
    line_obs_.reserve(max_lines);
    line_obs_feature_.reserve(max_lines);
    line_inlier_.reserve(max_lines);
    solver_.reserve(0, max_lines);
  }
  if (undistorted_.capacity() < static_cast<std::size_t>(p_.track.rows) * 4) undistorted_.reserve(p_.track.rows * 4);
  if (edgels_.size() < scene.cameras().size()) edgels_.resize(scene.cameras().size());
  for (auto& e : edgels_)
    if (e.capacity() < max_lines * static_cast<std::size_t>(p_.track.rows) * scene.objects().size())
      e.reserve(max_lines * static_cast<std::size_t>(p_.track.rows) * std::max<std::size_t>(1, scene.objects().size()));
  if (report_.objects.size() != scene.objects().size()) report_.objects.resize(scene.objects().size());
}

void VisionCycle::mark_ambiguous(scene::View& view, const scene::Camera& cam) const {
  // Two visible edges that project (almost) parallel, side by side and closer than a tracking
  // window is wide (a thin face seen edge-on, a double contour) cannot be told apart by their
  // windows: both are left out until the view separates them.
  const geometry::PinholeCamera& K = cam.intrinsics;
  const double max_dist = p_.track.half_width + p_.ambiguity_margin_px;
  const double cos_parallel = std::cos(p_.ambiguity_angle);
  for (scene::LineFeature& f : view.lines) {
    f.ambiguous = false;
    if (!f.visible && !f.grazing) continue;
    f.predicted.a = K.project(view.T_cam_obj * f.X1);
    f.predicted.b = K.project(view.T_cam_obj * f.X2);
  }
  const std::size_t n = view.lines.size();
  for (std::size_t i = 0; i < n; ++i) {
    scene::LineFeature& f = view.lines[i];
    if (!f.visible && !f.grazing) continue;
    const Eigen::Vector2d fa = f.predicted.a, fd = f.predicted.b - f.predicted.a;
    const double flen = fd.norm();
    if (flen < 1e-9) continue;
    const Eigen::Vector2d fu = fd / flen, fn(-fu.y(), fu.x());
    for (std::size_t j = i + 1; j < n; ++j) {
      scene::LineFeature& g = view.lines[j];
      if ((!g.visible && !g.grazing) || (f.grazing && g.grazing)) continue;
      const Eigen::Vector2d gd = g.predicted.b - g.predicted.a;
      const double glen = gd.norm();
      if (glen < 1e-9 || std::abs(fu.dot(gd) / glen) < cos_parallel) continue;
      // Side by side: g's ends near f's line, and the two overlap along f's direction.
      const double da = std::abs(fn.dot(g.predicted.a - fa)), db = std::abs(fn.dot(g.predicted.b - fa));
      if (std::min(da, db) > max_dist) continue;
      const double s0 = fu.dot(g.predicted.a - fa), s1 = fu.dot(g.predicted.b - fa);
      const double overlap = std::min(flen, std::max(s0, s1)) - std::max(0.0, std::min(s0, s1));
      if (overlap < p_.ambiguity_min_overlap * std::min(flen, glen)) continue;
      // Edges that share a junction and continue each other are not side by side.
      if (std::max(da, db) < 0.5 && (s0 >= flen - 0.5 || s1 <= 0.5)) continue;
      f.ambiguous = f.ambiguous || f.visible;
      g.ambiguous = g.ambiguous || g.visible;
    }
  }
}

int VisionCycle::track_features(scene::View& view, const scene::Camera& cam, const image::ImageView& img,
                                bool first_pass) {
  const geometry::PinholeCamera& K = cam.intrinsics;
  int found = 0;
  for (scene::LineFeature& f : view.lines) {
    if (!f.visible || f.ambiguous) continue;
    // The first pass measures every feature: features not found in the last frame are searched
    // in the wide window, found ones tracked in the narrow one. Later passes start from the fresh
    // pose and measure again, in the narrow window, only what was missed or rejected: a found
    // edge's line does not depend on where its window sat.
    if (first_pass || f.retrack) {
      const Eigen::Vector3d P1 = view.T_cam_obj * f.X1;
      const Eigen::Vector3d P2 = view.T_cam_obj * f.X2;
      f.predicted.a = K.project(P1);
      f.predicted.b = K.project(P2);
      const bool search = first_pass && f.status != scene::FeatureStatus::kFound;
      features::LineTracker& t = search ? searcher_ : tracker_;
      f.measurement = t.track(img, f.predicted, f.track);
      f.retrack = !f.measurement.found;
      if (f.measurement.found) {
        undistorted_line(K, f.measurement, t.last_inliers(), undistorted_, f.line_n1, f.line_n2);
        auto& out = edgels_[view.camera];
        for (const Eigen::Vector2d& p : t.last_inliers())
          if (out.size() < out.capacity()) out.push_back(p);
      }
    }
    if (f.measurement.found) ++found;
  }
  return found;
}

void VisionCycle::process_view(scene::Object& obj, scene::View& view, const scene::Camera& cam,
                               const image::ImageView& img, ObjectReport& rep) {
  const model::Model& model = *obj.model;
  const geometry::PinholeCamera& K = cam.intrinsics;
  const auto t0 = Clock::now();

  // Predict: the view pose from the object pose (constant-pose prediction; a motion model
  // plugs in here).
  view.T_cam_obj = cam.T_ref_cam.inverse() * obj.T_ref_obj;

  // Visibility and the visible part of every edge.
  visibility_.update(model, view.T_cam_obj, K, view.face_visible, std::span(edge_vis_.data(), model.lines().size()));
  for (scene::LineFeature& f : view.lines) {
    const EdgeVisibility& ev = edge_vis_[f.edge];
    f.visible = ev.visible;
    f.grazing = ev.grazing;
    if (!f.visible && !f.grazing) continue;
    const Eigen::Vector3d A = model.line_point_a(f.edge), B = model.line_point_b(f.edge);
    f.X1 = A + ev.s0 * (B - A);
    f.X2 = A + ev.s1 * (B - A);
  }
  mark_ambiguous(view, cam);
  int visible = 0;
  for (const scene::LineFeature& f : view.lines) visible += f.visible && !f.ambiguous ? 1 : 0;
  const auto t1 = Clock::now();
  report_.visibility_ms += ms_between(t0, t1);

  solver_.params() = p_.solver;
  solver_.params().focal_px = K.focal();
  estimation::PoseResult result;
  bool updated = false;
  int found = 0;
  const int passes = std::max(1, p_.refine_passes);
  for (int pass = 0; pass < passes; ++pass) {
    const auto ta = Clock::now();
    found = track_features(view, cam, img, pass == 0);
    const auto tb = Clock::now();
    report_.track_ms += ms_between(ta, tb);

    line_obs_.clear();
    line_obs_feature_.clear();
    for (std::size_t i = 0; i < view.lines.size(); ++i) {
      const scene::LineFeature& f = view.lines[i];
      if (!f.visible || f.ambiguous || !f.measurement.found) continue;
      estimation::LineObservation o;
      o.X1_obj = f.X1;
      o.X2_obj = f.X2;
      o.xn1 = f.line_n1;
      o.xn2 = f.line_n2;
      o.sigma_px = p_.line_sigma_px;
      line_obs_.push_back(o);
      line_obs_feature_.push_back(static_cast<std::uint32_t>(i));
    }
    line_inlier_.assign(line_obs_.size(), 1);
    if (static_cast<int>(line_obs_.size()) >= p_.min_lines) {
      result = solver_.solve(view.T_cam_obj, {}, line_obs_, {}, line_inlier_);
      if (result.ok() && result.inliers >= p_.min_lines) {
        view.T_cam_obj = result.T_cam_obj;
        updated = true;
      }
      for (std::size_t k = 0; k < line_obs_feature_.size(); ++k)
        if (!line_inlier_[k]) view.lines[line_obs_feature_[k]].retrack = true;
    }
    report_.solve_ms += ms_between(tb, Clock::now());
    if (!updated) break;
  }

  // Feature states after the last pass.
  int outliers = 0;
  for (scene::LineFeature& f : view.lines) {
    if (!f.visible || f.ambiguous) continue;
    if (f.measurement.found) {
      f.status = scene::FeatureStatus::kFound;
      f.frames_missing = 0;
    } else {
      if (f.status != scene::FeatureStatus::kNotFound) f.status = scene::FeatureStatus::kLost;
      if (++f.frames_missing >= 2) f.track.polarity = 0;  // the background may have changed side
    }
  }
  for (std::size_t k = 0; k < line_obs_feature_.size(); ++k) {
    if (line_inlier_[k]) continue;
    scene::LineFeature& f = view.lines[line_obs_feature_[k]];
    f.status = scene::FeatureStatus::kOutlier;
    f.track.polarity = 0;
    ++outliers;
  }
  view.pose = result;
  if (!updated) view.pose.status = result.ok() ? estimation::SolveStatus::kTooFewObservations : result.status;

  rep.features_visible += visible;
  rep.features_found += found;
  rep.features_used += updated ? result.inliers : 0;
  rep.outliers += updated ? outliers : 0;
  rep.rms_px = updated ? result.rms_px : 0.0;
  rep.iterations += result.iterations;
}

const CycleReport& VisionCycle::process(scene::Scene& scene, std::span<const image::ImageView> images) {
  const auto t0 = Clock::now();
  prepare(scene);
  report_.frame = frame_++;
  report_.visibility_ms = report_.track_ms = report_.solve_ms = 0.0;
  for (auto& e : edgels_) e.clear();

  auto& objects = scene.objects();
  for (std::size_t oi = 0; oi < objects.size(); ++oi) {
    scene::Object& obj = objects[oi];
    ObjectReport& rep = report_.objects[oi];
    rep = ObjectReport{};
    if (obj.status == scene::TrackStatus::kUninitialised) continue;

    for (scene::View& view : obj.views) {
      if (view.camera >= images.size() || images[view.camera].empty()) continue;
      process_view(obj, view, scene.cameras()[view.camera], images[view.camera], rep);
    }

    // Fuse the view poses into the object pose: information-weighted mean in the tangent space
    // of the first good view (one view: its pose, moved into the reference frame).
    const auto tf = Clock::now();
    const geometry::SE3* T0 = nullptr;
    geometry::SE3 T0_ref;
    geometry::Matrix6d info_sum = geometry::Matrix6d::Zero();
    geometry::Vector6d info_xi = geometry::Vector6d::Zero();
    int good = 0;
    for (const scene::View& view : obj.views) {
      if (!view.pose.ok()) continue;
      const scene::Camera& cam = scene.cameras()[view.camera];
      const geometry::SE3 T_ref = cam.T_ref_cam * view.T_cam_obj;
      const geometry::Matrix6d Ad = adjoint(cam.T_ref_cam);
      const geometry::Matrix6d cov = Ad * view.pose.covariance * Ad.transpose();
      if (!T0) {
        T0_ref = T_ref;
        T0 = &T0_ref;
      }
      const geometry::Matrix6d info = (cov + 1e-18 * geometry::Matrix6d::Identity()).inverse();
      info_sum += info;
      info_xi += info * (T_ref * T0_ref.inverse()).log();
      ++good;
    }
    if (good > 0) {
      const geometry::Matrix6d cov = info_sum.inverse();
      obj.T_ref_obj = geometry::SE3::exp(cov * info_xi) * T0_ref;
      obj.covariance = cov;
      const double ratio = rep.features_visible > 0 ? static_cast<double>(rep.features_used) / rep.features_visible : 0.0;
      obj.quality = std::clamp(ratio, 0.0, 1.0) / (1.0 + (rep.rms_px / 1.5) * (rep.rms_px / 1.5));
      obj.status = ratio >= p_.degraded_ratio ? scene::TrackStatus::kTracking : scene::TrackStatus::kDegraded;
    } else {
      obj.quality = 0.0;
      obj.status = scene::TrackStatus::kLost;
    }
    rep.status = obj.status;
    rep.quality = obj.quality;
    report_.solve_ms += ms_between(tf, Clock::now());

  }
  report_.cycle_ms = ms_between(t0, Clock::now());
  return report_;
}

}  // namespace v4r::pipeline
