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
      budget_(params.budget) {
  const auto n = static_cast<std::size_t>(std::clamp(params.threads, 1, 16));
  for (std::size_t k = 0; k < n; ++k) units_.push_back(std::make_unique<ObjectMeasurer>(params, now));
  for (const auto& u : units_) unit_ptrs_.push_back(u.get());
  if (n > 1) team_ = std::make_unique<ThreadTeam>(n);
}

void VisionCycle::set_params(const CycleParams& params) {
  const std::int64_t frame = frame_;
  const std::int64_t overruns = report_.overruns;
  *this = VisionCycle(params, now_);
  frame_ = frame;
  report_.overruns = overruns;
}

const std::vector<Eigen::Vector2d>& VisionCycle::edgels(std::size_t camera) const {
  // One thread: its unit's own; several: their merge (process()).
  if (units_.size() == 1) return units_[0]->edgels(camera);
  static const std::vector<Eigen::Vector2d> kEmpty;
  return camera < edgels_.size() ? edgels_[camera] : kEmpty;
}

void VisionCycle::prepare(const scene::Scene& scene) {
  std::size_t total = 0;
  for (const scene::Object& o : scene.objects()) total += (o.model->lines().size() + o.model->arcs().size()) * o.views.size();
  for (const auto& u : units_) u->reserve(scene);
  budget_.reserve(total);
  if (measured_.capacity() < scene.objects().size()) measured_.reserve(scene.objects().size());
  if (units_.size() > 1) {  // the units' edge pixels merged (edgels())
    if (edgels_.size() < scene.cameras().size()) edgels_.resize(scene.cameras().size());
    const std::size_t per_camera =
        std::max<std::size_t>(1, total) * static_cast<std::size_t>(p_.track.rows + 2 * scene::ArcFeature::kMaxSamples);
    for (auto& e : edgels_)
      if (e.capacity() < per_camera) e.reserve(per_camera);
  }
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

void VisionCycle::measure_object(scene::Scene& scene, std::span<const CameraImage> images, std::size_t oi,
                                 std::size_t unit, double stamp_s) {
  scene::Object& obj = scene.objects()[oi];
  ObjectReport& rep = report_.objects[oi];
  // One object's fault (a bug, bad_alloc, an OpenCV exception) must not end the others' cycle.
  try {
    if (object_hook_) object_hook_(obj);
    units_[unit]->measure(scene, obj, images, rep, stamp_s);
  } catch (const std::exception& e) {
    object_failed(obj, rep, e.what());
  } catch (...) {
    object_failed(obj, rep, "unknown exception");
  }
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

  // 3. Measure every view, solve, test the evidence, filter: with several threads, the objects
  // in parallel (object k of this frame on thread k % threads), or the views of the one object.
  measured_.clear();
  for (std::size_t oi = 0; oi < objects.size(); ++oi)
    if (scene::is_tracked(objects[oi].status) && !report_.objects[oi].failed) measured_.push_back(oi);
  for (const auto& u : units_) u->begin_frame(ctx_);
  const bool by_object = team_ && measured_.size() > 1;
  units_[0]->set_view_team(team_ && !by_object ? team_.get() : nullptr, unit_ptrs_);
  if (by_object) {
    struct Job {
      VisionCycle* self;
      scene::Scene* scene;
      std::span<const CameraImage> images;
      double stamp_s;
    } job{this, &scene, images, stamp_s};
    team_->run(
        measured_.size(),
        [](void* arg, std::size_t task, std::size_t member) {
          Job& j = *static_cast<Job*>(arg);
          j.self->measure_object(*j.scene, j.images, j.self->measured_[task], member, j.stamp_s);
        },
        &job);
  } else {
    for (const std::size_t oi : measured_) measure_object(scene, images, oi, 0, stamp_s);
  }
  // The units' counters summed, and (several units) their edge pixels merged.
  for (const auto& u : units_) {
    ctx_.samples += u->context().samples;
    ctx_.windows += u->context().windows;
    report_.track_ms += u->track_ms();
    report_.solve_ms += u->solve_ms();
    for (std::size_t c = 0; units_.size() > 1 && c < edgels_.size(); ++c) {
      const auto& e = u->edgels(c);
      const std::size_t room = edgels_[c].capacity() - edgels_[c].size();
      edgels_[c].insert(edgels_[c].end(), e.begin(), e.begin() + static_cast<std::ptrdiff_t>(std::min(room, e.size())));
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
