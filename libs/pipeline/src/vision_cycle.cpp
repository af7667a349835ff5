// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/vision_cycle.hpp"

#include <algorithm>
#include <cmath>

#include "v4r/pipeline/object_update.hpp"
#include "v4r/pipeline/view_evidence.hpp"

namespace v4r::pipeline {

VisionCycle::VisionCycle(const CycleParams& params, Clock::time_point (*now)())
    : p_(params),
      now_(now),
      predictor_(params),
      lines_(params),
      arcs_(params),
      junctions_(params),
      solver_(params),
      evidence_(params.status.evidence),
      budget_(params.budget) {}

void VisionCycle::set_params(const CycleParams& params) {
  const std::int64_t frame = frame_;
  const std::int64_t overruns = report_.overruns;
  *this = VisionCycle(params, now_);
  frame_ = frame;
  report_.overruns = overruns;
}

const std::vector<Eigen::Vector2d>& VisionCycle::edgels(std::size_t camera) const {
  static const std::vector<Eigen::Vector2d> kEmpty;
  return camera < edgels_.size() ? edgels_[camera] : kEmpty;
}

void VisionCycle::prepare(const scene::Scene& scene) {
  // Buffers for the largest object seen by every camera: observations of one solve come from all
  // views of one object.
  std::size_t lines = 0, junctions = 0, arcs = 0, total = 0, views = 1;
  for (const scene::Object& o : scene.objects()) {
    const std::size_t nv = std::max<std::size_t>(1, o.views.size());
    views = std::max(views, nv);
    lines = std::max(lines, o.model->lines().size() * nv);
    junctions = std::max(junctions, o.model->junctions().size() * nv);
    arcs = std::max(arcs, o.model->arcs().size() * nv);
    total += (o.model->lines().size() + o.model->arcs().size()) * o.views.size();
  }
  const std::size_t circle_points = arcs * scene::ArcFeature::kMaxSamples;
  if (buffer_.lines.capacity() < lines || buffer_.points.capacity() < junctions ||
      buffer_.circles.capacity() < circle_points || buffer_.cameras.capacity() < views) {
    buffer_.reserve(views, lines, junctions, circle_points);
    solver_.reserve(junctions, lines, circle_points);
  }
  if (solves_.capacity() < views) solves_.reserve(views);
  arcs_.reserve();
  budget_.reserve(total);
  if (edgels_.size() < scene.cameras().size()) edgels_.resize(scene.cameras().size());
  const std::size_t per_camera =
      std::max<std::size_t>(1, total) * static_cast<std::size_t>(p_.track.rows + 2 * scene::ArcFeature::kMaxSamples);
  for (auto& e : edgels_)
    if (e.capacity() < per_camera) e.reserve(per_camera);
  lines_.reserve(static_cast<std::size_t>(std::max({p_.track.rows, p_.budget.reduced_rows, 64})));
  if (report_.objects.size() != scene.objects().size()) report_.objects.resize(scene.objects().size());
}

void VisionCycle::predict_object(scene::Object& obj, ObjectReport& rep, double stamp_s) {
  rep.search_level = std::min(obj.bad_frames, p_.recovery.max_search_level);
  const double dt = obj.last_stamp >= 0.0 ? std::max(0.0, stamp_s - obj.last_stamp) : 0.0;
  // The filter predicts while the object is tracked, and through degraded frames once its
  // motion has been measured; a lost object, or a fresh start pose (whose first correction is
  // no motion), is held. The filter's time update of this frame is done once here: its pose
  // places the windows and its covariance weighs the prior; the measurement update follows in
  // update_object.
  const bool predict = obj.bad_frames == 0 || (obj.confirmed && obj.measured != scene::TrackStatus::kLost);
  obj.covariance_pred.setZero();
  filter::PoseFilterParams fp = p_.filter;
  fp.adapt_noise = false;
  obj.filter.set_params(fp);
  fp.adapt_noise = true;
  obj.smoother.set_params(fp);
  if (p_.use_filter) {
    obj.filter.predict(dt);
    if (p_.smooth_output) obj.smoother.predict(dt);
  }
  obj.T_pred = p_.use_filter && obj.filter.initialised() && predict ? obj.filter.pose() : obj.T_ref_obj;
  if (p_.use_filter && obj.filter.initialised()) obj.covariance_pred = obj.filter.pose_covariance();
}

namespace {

/// Radius of an origin-centred sphere that holds the whole model (junctions, arcs, cylinders).
double enclosing_radius(const model::Model& m) {
  double r = m.bounding_radius();
  for (const model::Cylinder& c : m.cylinders()) r = std::max(r, std::max(c.p1.norm(), c.p2.norm()) + c.radius);
  return r;
}

/// Whether an object (sphere of radius r_occ round the origin of T_cam_occ) may hide part of
/// another (r_obj round T_cam_obj's origin) in the camera: not wholly behind it, and their
/// spheres' image discs (angular radii, seen from the camera centre) overlap.
bool may_occlude(const geometry::SE3& T_cam_occ, double r_occ, const geometry::SE3& T_cam_obj, double r_obj) {
  const Eigen::Vector3d a = T_cam_occ.translation(), b = T_cam_obj.translation();
  if (a.z() - r_occ > b.z() + r_obj) return false;  // wholly behind
  const double da = a.norm(), db = b.norm();
  if (da <= r_occ || db <= r_obj) return true;  // the camera inside a sphere: keep it
  const double cos_between = std::clamp(a.dot(b) / (da * db), -1.0, 1.0);
  return std::acos(cos_between) <= std::asin(r_occ / da) + std::asin(r_obj / db);
}

}  // namespace

void VisionCycle::predict_views(scene::Scene& scene, std::span<const CameraImage> images) {
  auto objects = scene.objects();
  const auto tracked = [&](std::size_t oi) {
    return scene::is_tracked(objects[oi].status) && !report_.objects[oi].failed;
  };
  for (std::size_t c = 0; c < scene.cameras().size(); ++c) {
    if (c >= images.size() || images[c].grey.empty()) continue;
    const scene::Camera& cam = scene.cameras()[c];
    const geometry::SE3 T_cam_ref = cam.T_ref_cam.inverse();
    for (std::size_t oi = 0; oi < objects.size(); ++oi) {
      if (!tracked(oi)) continue;
      scene::Object& obj = objects[oi];
      try {
        // The other objects at their predictions hide what is behind them (paper 2.1: the scene);
        // only those whose bounding sphere can cover this one's in the image and is not wholly
        // behind it are tested (objects side by side cost nothing).
        predictor_.clear_occluders();
        const geometry::SE3 T_cam_obj = T_cam_ref * obj.T_pred;
        for (std::size_t oj = 0; oj < objects.size(); ++oj) {
          if (oj == oi || !tracked(oj)) continue;
          const geometry::SE3 T_cam_occ = T_cam_ref * objects[oj].T_pred;
          if (may_occlude(T_cam_occ, enclosing_radius(*objects[oj].model), T_cam_obj, enclosing_radius(*obj.model)))
            predictor_.add_occluder(*objects[oj].model, T_cam_occ);
        }
        for (scene::View& view : obj.views)
          if (view.camera == c) predictor_.predict(obj, view, cam);
      } catch (const std::exception& e) {
        object_failed(obj, report_.objects[oi], e.what());
      } catch (...) {
        object_failed(obj, report_.objects[oi], "unknown exception");
      }
    }
  }
}

ObjectSolve VisionCycle::measure_views(const scene::Scene& scene, scene::Object& obj,
                                       std::span<const CameraImage> images, std::size_t first, std::size_t last,
                                       ObjectReport& rep) {
  const auto has_image = [&](const scene::View& v) {
    return v.camera < images.size() && !images[v.camera].grey.empty();
  };
  const SolvePrior prior{obj.confirmed, obj.T_pred, obj.covariance_pred};
  ObjectSolve best;  // the last solve that measured the pose
  estimation::PoseResult last_result;
  geometry::SE3 T = obj.T_pred;
  int found = 0;
  ctx_.search_level = rep.search_level;
  const int passes = std::max(1, p_.refine_passes);
  for (int pass = 0; pass < passes; ++pass) {
    ctx_.first_pass = pass == 0;
    ctx_.refound = 0;
    const auto ta = now_();
    found = 0;
    for (std::size_t vi = first; vi < last; ++vi) {
      scene::View& view = obj.views[vi];
      if (!has_image(view)) continue;
      const scene::Camera& cam = scene.cameras()[view.camera];
      ctx_.edgels = view.camera < edgels_.size() ? &edgels_[view.camera] : nullptr;
      found += lines_.track(view, cam, images[view.camera], ctx_);
      found += arcs_.track(*obj.model, view, cam, images[view.camera], ctx_);
    }
    const auto tb = now_();
    report_.track_ms += ms_between(ta, tb);
    // A later pass whose re-measured features all failed again adds nothing: the last solve stands.
    if (pass > 0 && ctx_.refound == 0) break;

    buffer_.clear();
    for (std::size_t vi = first; vi < last; ++vi) {
      const scene::View& view = obj.views[vi];
      if (!has_image(view) || buffer_.cameras.size() >= estimation::kMaxSolveCameras) continue;
      const scene::Camera& cam = scene.cameras()[view.camera];
      const auto k = static_cast<std::uint8_t>(buffer_.cameras.size());
      buffer_.cameras.push_back(estimation::SolveCamera{cam.T_ref_cam.inverse(), cam.intrinsics.focal()});
      lines_.observations(view, static_cast<std::uint16_t>(vi), k, buffer_);
      junctions_.observations(*obj.model, view, cam, k, buffer_);
      arcs_.observations(*obj.model, view, cam, static_cast<std::uint16_t>(vi), k, buffer_);
    }
    const ObjectSolve s = solver_.solve(T, buffer_, prior);
    last_result = s.result;
    if (s.updated) {
      best = s;
      T = s.T_ref_obj;
      for (std::size_t vi = first; vi < last; ++vi)
        obj.views[vi].T_cam_obj = scene.cameras()[obj.views[vi].camera].T_ref_cam.inverse() * T;
    }
    // Rejected lines, and ellipses with most edge points rejected, are measured again.
    for (std::size_t k = 0; k < buffer_.line_refs.size(); ++k)
      if (!buffer_.line_inliers[k]) obj.views[buffer_.line_refs[k].view].lines[buffer_.line_refs[k].feature].retrack = true;
    for (std::size_t k = 0, start = 0; k <= buffer_.circle_refs.size(); ++k) {
      const auto same = [&](std::size_t a, std::size_t b) {
        return buffer_.circle_refs[a].view == buffer_.circle_refs[b].view &&
               buffer_.circle_refs[a].feature == buffer_.circle_refs[b].feature;
      };
      if (k < buffer_.circle_refs.size() && same(k, start)) continue;
      if (k > start) {
        int bad = 0;
        for (std::size_t q = start; q < k; ++q) bad += buffer_.circle_inliers[q] ? 0 : 1;
        const FeatureRef& r = buffer_.circle_refs[start];
        if (2 * bad > static_cast<int>(k - start)) obj.views[r.view].arcs[r.feature].retrack = true;
      }
      start = k;
    }
    report_.solve_ms += ms_between(tb, now_());
    if (!s.updated) break;
  }

  // Feature states after the last pass.
  const auto settle = [](auto& f) {
    if (f.measurement.found) {
      f.status = scene::FeatureStatus::kFound;
      f.frames_missing = 0;
    } else {
      if (f.status != scene::FeatureStatus::kNotFound) f.status = scene::FeatureStatus::kLost;
      if (++f.frames_missing >= 2) f.track.polarity = 0;  // the background may have changed side
    }
  };
  for (std::size_t vi = first; vi < last; ++vi) {
    scene::View& view = obj.views[vi];
    if (!has_image(view)) continue;
    for (scene::LineFeature& f : view.lines)
      if (f.visible && !f.ambiguous && !f.dropped) settle(f);
    for (scene::ArcFeature& a : view.arcs)
      if (a.visible && !a.dropped) settle(a);
  }
  int outliers = 0, lines_used = 0, circle_used = 0, junctions_used = 0;
  for (std::size_t k = 0; k < buffer_.line_refs.size(); ++k) {
    if (buffer_.line_inliers[k]) {
      ++lines_used;
      continue;
    }
    scene::LineFeature& f = obj.views[buffer_.line_refs[k].view].lines[buffer_.line_refs[k].feature];
    f.status = scene::FeatureStatus::kOutlier;
    f.track.polarity = 0;
    ++outliers;
  }
  for (const std::uint8_t in : buffer_.circle_inliers) {
    circle_used += in;
    outliers += 1 - in;
  }
  for (const std::uint8_t in : buffer_.point_inliers) {
    junctions_used += in;
    outliers += 1 - in;
  }
  rep.features_found += found;
  if (best.updated) {
    rep.features_used += last_result.inliers;
    rep.lines_used += lines_used;
    rep.circle_points_used += circle_used;
    rep.junctions_used += junctions_used;
    rep.tangent_junctions += buffer_.tangent_junctions;
    rep.outliers += outliers;
    rep.rms_px = last_result.rms_px;
  }
  rep.iterations += last_result.iterations;
  rep.prior_used = rep.prior_used || best.prior_used;
  return best;
}

void VisionCycle::measure_object(const scene::Scene& scene, scene::Object& obj, std::span<const CameraImage> images,
                                 ObjectReport& rep, double stamp_s) {
  for (scene::View& view : obj.views) {
    if (view.camera >= images.size() || images[view.camera].grey.empty()) continue;
    for (const scene::LineFeature& f : view.lines) rep.features_visible += f.visible && !f.ambiguous && !f.dropped ? 1 : 0;
    for (const scene::ArcFeature& a : view.arcs) rep.features_visible += a.visible && !a.dropped ? 1 : 0;
  }
  // One solve over every view (CycleParams::joint_solve), or one per view, fused.
  solves_.clear();
  if (p_.joint_solve) {
    solves_.push_back(measure_views(scene, obj, images, 0, obj.views.size(), rep));
  } else {
    for (std::size_t vi = 0; vi < obj.views.size() && solves_.size() < solves_.capacity(); ++vi)
      solves_.push_back(measure_views(scene, obj, images, vi, vi + 1, rep));
  }
  // Image evidence at the measured pose, per view.
  for (scene::View& view : obj.views) {
    view.evidence_samples = view.evidence_matched = 0;
    if (view.camera >= images.size() || images[view.camera].grey.empty()) continue;
    measure_view_evidence(evidence_, view, scene.cameras()[view.camera], images[view.camera]);
  }
  const auto tf = now_();
  update_object(obj, combine_solves(solves_), p_, rep, stamp_s);
  report_.solve_ms += ms_between(tf, now_());
}

void VisionCycle::object_failed(scene::Object& obj, ObjectReport& rep, const char* what) const {
  obj.status = scene::TrackStatus::kUninitialised;
  obj.quality = 0.0;
  rep.status = scene::TrackStatus::kUninitialised;
  rep.failed = true;
  try {
    rep.error = what;
  } catch (...) {  // out of memory: the flag alone must do
  }
}

const CycleReport& VisionCycle::process(scene::Scene& scene, std::span<const CameraImage> images, double stamp_s) {
  const auto t0 = now_();
  prepare(scene);
  if (stamp_s < 0.0) stamp_s = static_cast<double>(frame_) * p_.frame_interval_s;
  report_.frame = frame_;
  report_.stamp_s = stamp_s;
  report_.visibility_ms = report_.track_ms = report_.solve_ms = 0.0;
  report_.windows = 0;
  ctx_ = MeasureContext{};
  ctx_.frame = ++frame_;  // (the back-off phase: frames counted from 1)
  for (auto& e : edgels_) e.clear();
  auto objects = scene.objects();

  // 1. Predict every object; then, per camera, what each of its views can see.
  for (std::size_t oi = 0; oi < objects.size(); ++oi) {
    scene::Object& obj = objects[oi];
    ObjectReport& rep = report_.objects[oi];
    rep = ObjectReport{};
    if (obj.status == scene::TrackStatus::kUninitialised) continue;
    // An object being searched for is left to pipeline::ObjectSearch (issue 10).
    if (obj.status == scene::TrackStatus::kSearching) {
      rep.status = obj.status;
      continue;
    }
    // One object's fault (a bug, bad_alloc, an OpenCV exception) must not end the others' cycle.
    try {
      predict_object(obj, rep, stamp_s);
    } catch (const std::exception& e) {
      object_failed(obj, rep, e.what());
    } catch (...) {
      object_failed(obj, rep, "unknown exception");
    }
  }
  predict_views(scene, images);
  const auto t1 = now_();
  report_.visibility_ms = ms_between(t0, t1);

  // 2. Keep the time budget: fewer samples, then fewer features.
  plan_ = budget_.plan(scene, p_);
  report_.degrade_level = plan_.degrade_level;
  report_.features_dropped = plan_.features_dropped;
  ctx_.degrade_level = plan_.degrade_level;
  ctx_.samples_per_circle = plan_.samples_per_circle;

  // 3. Measure every view, solve, test the evidence, filter.
  for (std::size_t oi = 0; oi < objects.size(); ++oi) {
    scene::Object& obj = objects[oi];
    ObjectReport& rep = report_.objects[oi];
    if (!scene::is_tracked(obj.status) || rep.failed) continue;
    try {
      if (object_hook_) object_hook_(obj);
      measure_object(scene, obj, images, rep, stamp_s);
    } catch (const std::exception& e) {
      object_failed(obj, rep, e.what());
    } catch (...) {
      object_failed(obj, rep, "unknown exception");
    }
  }

  // Learn the cost of a sample for the next budget decision.
  budget_.learn(report_.track_ms, ctx_.samples);
  report_.windows = ctx_.windows;
  report_.cycle_ms = ms_between(t0, now_());
  if (p_.budget.cycle_ms > 0.0 && report_.cycle_ms > p_.budget.cycle_ms) ++report_.overruns;
  return report_;
}

}  // namespace v4r::pipeline
