// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/object_measurer.hpp"

#include <algorithm>
#include <array>

#include "v4r/pipeline/object_update.hpp"
#include "v4r/pipeline/view_evidence.hpp"

namespace v4r::pipeline {

ObjectMeasurer::ObjectMeasurer(const CycleParams& params, Clock::time_point (*now)())
    : p_(params),
      now_(now),
      lines_(params),
      arcs_(params),
      junctions_(params),
      solver_(params),
      evidence_(params.status.evidence),
      contrast_(params.status.contrast),
      samples_(params.samples) {}

void ObjectMeasurer::reserve(const scene::Scene& scene) {
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
  if (edgels_.size() < scene.cameras().size()) edgels_.resize(scene.cameras().size());
  const std::size_t per_camera =
      std::max<std::size_t>(1, total) * static_cast<std::size_t>(p_.track.rows + 2 * scene::ArcFeature::kMaxSamples);
  for (auto& e : edgels_)
    if (e.capacity() < per_camera) e.reserve(per_camera);
  lines_.reserve(static_cast<std::size_t>(std::max({p_.track.rows, p_.budget.reduced_rows, 64})));
  samples_.reserve();
}

void ObjectMeasurer::begin_frame(const MeasureContext& cycle) {
  ctx_ = cycle;
  track_ms_ = solve_ms_ = 0.0;
  for (auto& e : edgels_) e.clear();
}

void ObjectMeasurer::set_view_team(ThreadTeam* team, std::span<ObjectMeasurer* const> peers) {
  view_team_ = team;
  peers_ = peers;
}

ObjectMeasurer::TrackStep ObjectMeasurer::track_view(const scene::Scene& scene, const scene::Object& obj,
                                                           scene::View& view, std::span<const CameraImage> images) {
  const scene::Camera& cam = scene.cameras()[view.camera];
  const int refound = ctx_.refound;
  ctx_.edgels = view.camera < edgels_.size() ? &edgels_[view.camera] : nullptr;
  TrackStep step;
  step.found += lines_.track(view, cam, images[view.camera], ctx_);
  step.found += arcs_.track(*obj.model, view, cam, images[view.camera], ctx_);
  step.refound = ctx_.refound - refound;
  return step;
}

ObjectMeasurer::TrackStep ObjectMeasurer::track_views(const scene::Scene& scene, scene::Object& obj,
                                                            std::span<const CameraImage> images, std::size_t first,
                                                            std::size_t last) {
  const auto has_image = [&](const scene::View& v) {
    return v.camera < images.size() && !images[v.camera].grey.empty();
  };
  TrackStep total;
  if (view_team_ == nullptr || view_team_->size() < 2 || last - first < 2 || peers_.size() < view_team_->size()) {
    for (std::size_t vi = first; vi < last; ++vi) {
      if (!has_image(obj.views[vi])) continue;
      const TrackStep s = track_view(scene, obj, obj.views[vi], images);
      total.found += s.found;
      total.refound += s.refound;
    }
    return total;
  }
  // View k on member k % size, each with its own unit's scratch; the pass state is this unit's.
  struct Job {
    ObjectMeasurer* self;
    const scene::Scene* scene;
    scene::Object* obj;
    std::span<const CameraImage> images;
    std::size_t first;
    TrackStep steps[16];  // per member (CycleParams::threads <= 16)
  } job{this, &scene, &obj, images, first, {}};
  for (ObjectMeasurer* peer : peers_.first(view_team_->size())) {
    if (peer == this) continue;
    peer->ctx_.first_pass = ctx_.first_pass;
    peer->ctx_.search_level = ctx_.search_level;
  }
  view_team_->run(
      last - first,
      [](void* arg, std::size_t task, std::size_t member) {
        Job& j = *static_cast<Job*>(arg);
        scene::View& view = j.obj->views[j.first + task];
        if (view.camera >= j.images.size() || j.images[view.camera].grey.empty() || member >= 16) return;
        ObjectMeasurer& unit = member == 0 ? *j.self : *j.self->peers_[member];
        const TrackStep s = unit.track_view(*j.scene, *j.obj, view, j.images);
        j.steps[member].found += s.found;
        j.steps[member].refound += s.refound;
      },
      &job);
  for (const TrackStep& s : job.steps) {
    total.found += s.found;
    total.refound += s.refound;
  }
  return total;
}

ObjectSolve ObjectMeasurer::measure_views(const scene::Scene& scene, scene::Object& obj,
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
    const auto ta = now_();
    const TrackStep step = track_views(scene, obj, images, first, last);
    found = step.found;
    const auto tb = now_();
    track_ms_ += ms_between(ta, tb);
    // A later pass whose re-measured features all failed again adds nothing: the last solve stands.
    if (pass > 0 && step.refound == 0) break;

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
    solve_ms_ += ms_between(tb, now_());
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

ObjectReport::SampleFit ObjectMeasurer::choose_sample_pose(const scene::Scene& scene, scene::Object& obj,
                                                           const geometry::SE3& T_ref_predicted,
                                                           std::span<const CameraImage> images,
                                                           features::SilhouetteContrast* contrast) {
  using Fit = ObjectReport::SampleFit;
  // The views with an image (at most SampleRefiner::kMaxViews); the first one's camera carries the pose.
  std::array<std::size_t, SampleRefiner::kMaxViews> vis{};
  std::size_t nv = 0;
  for (std::size_t vi = 0; vi < obj.views.size() && nv < vis.size(); ++vi) {
    const std::size_t c = obj.views[vi].camera;
    if (c < images.size() && !images[c].grey.empty()) vis[nv++] = vi;
  }
  if (nv == 0) return Fit::kNotRun;
  // Only where the line solve leaves doubt (samples.always: every frame): a visible edge it did
  // not use (rejected, or not found; circles too with samples.arcs_doubt) in any view. Edges left
  // out as side by side with another are no doubt: a face seen edge-on or a thin plate always has them.
  bool doubt = p_.samples.always;
  // A feature missed for longer than samples.recent_frames is no new doubt (an edge the image
  // never shows, hidden by a part the model lacks).
  const int recent = p_.samples.recent_frames;
  const auto unused = [&](const auto& f) {
    return f.status == scene::FeatureStatus::kOutlier ||
           (f.status != scene::FeatureStatus::kFound && (recent <= 0 || f.frames_missing <= recent));
  };
  for (std::size_t k = 0; k < nv; ++k) {
    const scene::View& view = obj.views[vis[k]];
    for (const scene::LineFeature& f : view.lines) doubt = doubt || (f.visible && !f.ambiguous && unused(f));
    for (const scene::ArcFeature& a : view.arcs) doubt = doubt || (p_.samples.arcs_doubt && a.visible && !a.dropped && unused(a));
  }
  if (!doubt) return Fit::kNotRun;
  // The share of matched edge samples over the views (at the line solve's pose until the samples'
  // pose is tested below).
  const auto share = [&] {
    int samples = 0, matched = 0;
    for (std::size_t k = 0; k < nv; ++k) {
      samples += obj.views[vis[k]].evidence_samples;
      matched += obj.views[vis[k]].evidence_matched;
    }
    return samples > 0 ? static_cast<double>(matched) / samples : 0.0;
  };
  // A line pose the image confirms well leaves no doubt worth the samples' cost.
  const double lines_share = share();
  if (!p_.samples.always && p_.samples.doubt_evidence < 1.0 && lines_share >= p_.samples.doubt_evidence) return Fit::kNotRun;
  const auto camera = [&](std::size_t k) -> const scene::Camera& { return scene.cameras()[obj.views[vis[k]].camera]; };
  const geometry::SE3 T_first_ref = camera(0).T_ref_cam.inverse();
  std::array<SampleView, SampleRefiner::kMaxViews> sv;
  for (std::size_t k = 0; k < nv; ++k) {
    const scene::View& view = obj.views[vis[k]];
    // Gradients count from the lowest threshold the view's tracked edges needed (noise, texture).
    double threshold = view_threshold(view);
    if (!(threshold > 0.0)) threshold = p_.track.min_gradient;
    sv[k] = SampleView{&view, &camera(k).intrinsics, images[view.camera].grey, threshold,
                       k == 0 ? geometry::SE3{} : camera(k).T_ref_cam.inverse() * camera(0).T_ref_cam};
  }
  geometry::SE3 T = T_first_ref * T_ref_predicted;  // the object in the first view's camera
  const auto tb = now_();
  const bool refined = samples_.refine(*obj.model, std::span<const SampleView>(sv.data(), nv), T);
  solve_ms_ += ms_between(tb, now_());
  if (!refined) return Fit::kRun;
  const geometry::SE3 T_ref = camera(0).T_ref_cam * T;
  // The line solve's poses; a per-sample pose within samples.same_px of it (in every view)
  // changes nothing.
  struct Kept {
    geometry::SE3 T_lines;
    int samples = 0, matched = 0, leak_samples = 0, leak_matched = 0;
  };
  std::array<Kept, SampleRefiner::kMaxViews> kept;
  double shift = 0.0;  // px: the largest move of a visible edge's end
  for (std::size_t k = 0; k < nv; ++k) {
    const scene::View& view = obj.views[vis[k]];
    const geometry::SE3 Tv = sv[k].T_cam_first * T;
    kept[k] = Kept{view.T_cam_obj, view.evidence_samples, view.evidence_matched, view.leak_samples, view.leak_matched};
    const geometry::PinholeCamera& K = camera(k).intrinsics;
    for (const scene::LineFeature& f : view.lines) {
      if (!f.visible) continue;
      for (const Eigen::Vector3d& X : {f.X1, f.X2}) {
        const Eigen::Vector3d a = Tv * X, b = view.T_cam_obj * X;
        if (a.z() > 1e-3 && b.z() > 1e-3) shift = std::max(shift, (K.project(a) - K.project(b)).norm());
      }
    }
  }
  if (!(shift >= p_.samples.same_px)) return Fit::kRun;
  // Kept unless the image confirms the samples' pose better (its colour test is taken in the same
  // pass, and dropped with the pose).
  for (std::size_t k = 0; k < nv; ++k) {
    scene::View& view = obj.views[vis[k]];
    view.T_cam_obj = sv[k].T_cam_first * T;
    measure_view_evidence(evidence_, contrast, view, camera(k), images[view.camera]);
  }
  if (share() > lines_share + p_.samples.margin) {
    solves_[0].T_ref_obj = T_ref;
    return Fit::kKept;
  }
  for (std::size_t k = 0; k < nv; ++k) {
    scene::View& view = obj.views[vis[k]];
    view.T_cam_obj = kept[k].T_lines;
    view.evidence_samples = kept[k].samples;
    view.evidence_matched = kept[k].matched;
    view.leak_samples = kept[k].leak_samples;
    view.leak_matched = kept[k].leak_matched;
  }
  return Fit::kRun;
}

void ObjectMeasurer::measure(const scene::Scene& scene, scene::Object& obj, std::span<const CameraImage> images,
                                ObjectReport& rep, double stamp_s) {
  for (scene::View& view : obj.views) {
    if (view.camera >= images.size() || images[view.camera].grey.empty()) continue;
    for (const scene::LineFeature& f : view.lines) rep.features_visible += f.visible && !f.ambiguous && !f.dropped ? 1 : 0;
    for (const scene::ArcFeature& a : view.arcs) rep.features_visible += a.visible && !a.dropped ? 1 : 0;
  }
  // The per-sample measurement starts from the predicted pose.
  const geometry::SE3 T_ref_predicted = obj.T_pred;
  // One solve over every view (CycleParams::joint_solve), or one per view, fused.
  solves_.clear();
  if (p_.joint_solve) {
    solves_.push_back(measure_views(scene, obj, images, 0, obj.views.size(), rep));
  } else {
    for (std::size_t vi = 0; vi < obj.views.size() && solves_.size() < solves_.capacity(); ++vi)
      solves_.push_back(measure_views(scene, obj, images, vi, vi + 1, rep));
  }
  // Image evidence at the measured pose, per view; the silhouette's colours on every
  // status.leak_period-th frame.
  const bool leak_due = obj.leak_wait <= 0;
  obj.leak_wait = leak_due ? std::max(0, p_.status.leak_period - 1) : obj.leak_wait - 1;
  features::SilhouetteContrast* const contrast = leak_due ? &contrast_ : nullptr;
  for (scene::View& view : obj.views) {
    view.evidence_samples = view.evidence_matched = 0;
    view.leak_samples = view.leak_matched = 0;
    if (view.camera >= images.size() || images[view.camera].grey.empty()) continue;
    measure_view_evidence(evidence_, contrast, view, scene.cameras()[view.camera], images[view.camera]);
  }
  // The samples search 3 px about the prediction: only once the image has confirmed the pose
  // since it was set (scene::Object::confirmed). A start pose, or a pose found on an earlier
  // frame, may be off, and the fit would hold it in place against the line solve's move.
  if (p_.samples.enabled && solves_.size() == 1 && solves_[0].updated && obj.confirmed)
    rep.sample_fit = choose_sample_pose(scene, obj, T_ref_predicted, images, contrast);
  const auto tf = now_();
  update_object(obj, combine_solves(solves_), p_, rep, stamp_s);
  solve_ms_ += ms_between(tf, now_());
}

}  // namespace v4r::pipeline
