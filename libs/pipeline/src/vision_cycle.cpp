// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/vision_cycle.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace v4r::pipeline {

namespace {

constexpr double kTwoPi = 6.283185307179586;

features::LineTrackerParams line_params(const CycleParams& p, int half_width, int rows) {
  features::LineTrackerParams s = p.track;
  s.half_width = half_width;
  s.rows = rows;
  return s;
}

features::EllipseTrackerParams ellipse_params(const CycleParams& p, int half_length, int max_samples) {
  features::EllipseTrackerParams e = p.ellipse;
  e.half_length = half_length;
  e.max_samples = max_samples;
  return e;
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

/// Homogeneous image line through two normalised points.
Eigen::Vector3d line_through(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return Eigen::Vector3d(a.x(), a.y(), 1.0).cross(Eigen::Vector3d(b.x(), b.y(), 1.0));
}

}  // namespace

VisionCycle::VisionCycle(const CycleParams& params, Clock::time_point (*now)())
    : p_(params),
      now_(now),
      tracker_(params.track),
      reduced_tracker_(line_params(params, params.track.half_width, std::max(3, params.budget.reduced_rows))),
      ellipse_tracker_(params.ellipse),
      ellipse_searcher_(ellipse_params(params, std::max(params.ellipse.half_length, params.search_half_width),
                                       params.ellipse.max_samples)),
      reduced_ellipse_tracker_(ellipse_params(params, params.ellipse.half_length, std::max(8, params.ellipse.max_samples / 2))),
      evidence_(params.status.evidence),
      solver_(params.solver),
      visibility_(params.visibility) {
  const int levels = std::max(0, params.recovery.max_search_level) + 1;
  searchers_.reserve(levels);
  for (int L = 0; L < levels; ++L) {
    // Level 0 searches new and lost features; higher levels search wider and coarser after bad frames.
    const int rows = L == 0 ? params.track.rows : std::max(8, params.track.rows / 2);
    searchers_.emplace_back(line_params(params, params.search_half_width * (1 + L), rows));
  }
}

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
  std::size_t max_lines = 0, max_junctions = 0, max_arcs = 0, total = 0;
  for (const scene::Object& o : scene.objects()) {
    max_lines = std::max(max_lines, o.model->lines().size());
    max_junctions = std::max(max_junctions, o.model->junctions().size());
    max_arcs = std::max(max_arcs, o.model->arcs().size());
    total += (o.model->lines().size() + o.model->arcs().size()) * o.views.size();
  }
  const std::size_t max_circle_points = max_arcs * scene::ArcFeature::kMaxSamples;
  if (edge_vis_.size() < max_lines) edge_vis_.resize(max_lines);
  if (line_obs_.capacity() < max_lines || point_obs_.capacity() < max_junctions ||
      circle_obs_.capacity() < max_circle_points) {
    line_obs_.reserve(max_lines);
    line_obs_feature_.reserve(max_lines);
    line_inlier_.reserve(max_lines);
    point_obs_.reserve(max_junctions);
    point_inlier_.reserve(max_junctions);
    circle_obs_.reserve(max_circle_points);
    circle_obs_feature_.reserve(max_circle_points);
    circle_inlier_.reserve(max_circle_points);
    solver_.reserve(max_junctions, max_lines, max_circle_points);
  }
  if (curve_.capacity() < static_cast<std::size_t>(scene::ArcFeature::kMaxSamples)) curve_.reserve(scene::ArcFeature::kMaxSamples);
  if (drop_scores_.capacity() < total) drop_scores_.reserve(total);
  if (edgels_.size() < scene.cameras().size()) edgels_.resize(scene.cameras().size());
  const std::size_t per_camera = std::max<std::size_t>(1, total) * static_cast<std::size_t>(p_.track.rows + 2 * scene::ArcFeature::kMaxSamples);
  for (auto& e : edgels_)
    if (e.capacity() < per_camera) e.reserve(per_camera);
  const std::size_t rows = static_cast<std::size_t>(std::max({p_.track.rows, p_.budget.reduced_rows, 64}));
  if (undistorted_.capacity() < rows * 4) undistorted_.reserve(rows * 4);
  if (report_.objects.size() != scene.objects().size()) report_.objects.resize(scene.objects().size());
}

void VisionCycle::predict_view(scene::Object& obj, scene::View& view, const scene::Camera& cam) {
  const model::Model& model = *obj.model;
  const geometry::PinholeCamera& K = cam.intrinsics;
  view.T_cam_obj = cam.T_ref_cam.inverse() * obj.T_pred;

  // Visibility and the visible part of every edge.
  visibility_.update(model, view.T_cam_obj, K, view.face_visible, std::span(edge_vis_.data(), model.lines().size()));
  const Eigen::Matrix3d R = view.T_cam_obj.rotation();
  for (scene::LineFeature& f : view.lines) {
    const EdgeVisibility& ev = edge_vis_[f.edge];
    f.visible = ev.visible;
    f.grazing = ev.grazing;
    f.dropped = false;
    f.retrack = false;
    if (!f.visible && !f.grazing) continue;
    const Eigen::Vector3d A = model.line_point_a(f.edge), B = model.line_point_b(f.edge);
    f.X1 = A + ev.s0 * (B - A);
    f.X2 = A + ev.s1 * (B - A);
  }
  mark_ambiguous(view, cam);

  // Which side of each visible edge shows the object (its visible faces), for cue integration.
  const auto& faces = model.faces();
  for (scene::LineFeature& f : view.lines) {
    if (!f.visible || f.ambiguous) continue;
    const model::LineEdge& e = model.lines()[f.edge];
    const Eigen::Vector2d a = f.predicted.a, d = f.predicted.b - f.predicted.a;
    const Eigen::Vector2d n(-d.y(), d.x());
    bool side[2] = {false, false};
    for (const model::Index fi : {e.face_left, e.face_right}) {
      if (fi == model::kNone || !view.face_visible[fi]) continue;
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (const model::Index j : faces[fi].loop) c += model.junctions()[j].p;
      c /= static_cast<double>(faces[fi].loop.size());
      const Eigen::Vector3d pc = view.T_cam_obj * c;
      if (pc.z() <= 1e-6) continue;
      side[n.dot(K.project(pc) - a) > 0 ? 1 : 0] = true;
    }
    f.track.side[0].is_object = side[0];
    f.track.side[1].is_object = side[1];
  }

  // Circle arcs: tracking lines at evenly spaced visible points of the projected circle.
  const auto& arcs = model.arcs();
  for (scene::ArcFeature& a : view.arcs) {
    const model::CircleArc& arc = arcs[a.arc];
    a.visible = false;
    a.dropped = false;
    a.retrack = false;
    a.samples = 0;
    const Eigen::Vector3d c_cam = view.T_cam_obj * arc.center;
    const Eigen::Vector3d n_cam = R * arc.normal;
    if (c_cam.z() <= 1e-6 || std::abs(n_cam.dot(c_cam.normalized())) < p_.circle_min_cos) continue;  // edge-on
    if (arc.face != model::kNone && arc.face < view.face_visible.size() && !view.face_visible[arc.face]) continue;
    const double span = std::clamp(arc.end - arc.start, 0.0, kTwoPi);
    const int n = std::clamp(static_cast<int>(std::lround(p_.circle_samples * span / kTwoPi)), 8,
                             scene::ArcFeature::kMaxSamples);
    const Eigen::Vector3d y_axis = arc.normal.cross(arc.x_axis);
    const bool full = span >= kTwoPi - 1e-9;
    for (int k = 0; k < n; ++k) {
      const double th = arc.start + span * (full ? static_cast<double>(k) / n : (k + 0.5) / n);
      const Eigen::Vector3d X = arc.center + arc.radius * (std::cos(th) * arc.x_axis + std::sin(th) * y_axis);
      const Eigen::Vector3d P = view.T_cam_obj * X;
      if (P.z() <= 1e-3 || !K.in_image(K.project(P), p_.visibility.image_margin + p_.ellipse.half_length)) continue;
      if (visibility_.hidden(P, arc.face)) continue;
      a.X[a.samples++] = X;
    }
    a.visible = a.samples >= 8;
  }
}

void VisionCycle::mark_ambiguous(scene::View& view, const scene::Camera& cam) const {
  // Two visible edges that project (almost) parallel, side by side and closer than a tracking
  // window is wide (a thin face seen obliquely, a double contour) would both find the stronger
  // edge in their windows. Their windows are split half way between them (each searches only
  // its own side); when that leaves less than split_min_px towards the other edge, the pair is
  // tracked as one: the visible one (the first of two) is measured against the pair's mid-line
  // with a sigma widened by half their separation, and the other is left out (a thin plate's
  // two edges, a face seen edge-on whose far edge runs along the silhouette).
  const geometry::PinholeCamera& K = cam.intrinsics;
  // (The wide search window reaches further than the tracking window.)
  const double max_dist =
      (p_.track_side_by_side ? std::max(p_.track.half_width, p_.search_half_width) : p_.track.half_width) +
      p_.ambiguity_margin_px;
  const double cos_parallel = std::cos(p_.ambiguity_angle);
  for (scene::LineFeature& f : view.lines) {
    f.ambiguous = false;
    f.merged = false;
    f.sigma_px = 0.0;
    f.range = features::SearchRange{};
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
      // Split: each window ends half way to the other edge (signed offsets along its normal).
      const double s_g = 0.5 * (fn.dot(g.predicted.a - fa) + fn.dot(g.predicted.b - fa));  // g seen from f
      const Eigen::Vector2d gu = gd / glen, gn(-gu.y(), gu.x());
      const double s_f = gn.dot(0.5 * (f.predicted.a + f.predicted.b) - g.predicted.a);   // f seen from g
      const auto limit = [](features::SearchRange& r, double s) {
        if (s > 0.0) r.hi = std::min(r.hi, 0.5 * s);
        else r.lo = std::max(r.lo, 0.5 * s);
      };
      limit(f.range, s_g);
      limit(g.range, s_f);
      if (!p_.track_side_by_side) {  // both left out until the view separates them
        f.range = g.range = features::SearchRange{};
        f.ambiguous = f.ambiguous || f.visible;
        g.ambiguous = g.ambiguous || g.visible;
        continue;
      }
      if (std::abs(s_g) < 2.0 * p_.split_min_px || std::abs(s_f) < 2.0 * p_.split_min_px) {
        scene::LineFeature& keep = f.visible && !f.ambiguous ? f : g;
        scene::LineFeature& other = &keep == &f ? g : f;
        if (!keep.visible || keep.ambiguous || keep.merged || other.merged) {
          f.ambiguous = f.ambiguous || f.visible;  // a third edge in the pair: too crowded
          g.ambiguous = g.ambiguous || g.visible;
          continue;
        }
        // Mid-line: keep's ends moved half way to their closest points on the other's line.
        const Eigen::Vector3d o1 = other.X1, ou = (other.X2 - other.X1).normalized();
        const auto mid = [&](const Eigen::Vector3d& X) { return 0.5 * (X + o1 + ou * ou.dot(X - o1)); };
        keep.X1 = mid(keep.X1);
        keep.X2 = mid(keep.X2);
        keep.merged = true;
        keep.sigma_px = p_.line_sigma_px + 0.5 * std::abs(s_g);
        keep.range = features::SearchRange{};
        other.ambiguous = other.ambiguous || other.visible;
      }
    }
  }
}

void VisionCycle::plan_budget(scene::Scene& scene) {
  degrade_level_ = 0;
  rows_per_line_ = p_.track.rows;
  samples_per_circle_ = p_.ellipse.max_samples;
  report_.degrade_level = 0;
  report_.features_dropped = 0;
  if (p_.budget.cycle_ms <= 0.0) return;
  const double available_us = p_.budget.cycle_ms * 1000.0 * (1.0 - p_.budget.reserve_fraction);
  const double cost = p_.budget.cost_per_sample_us;
  auto predicted_us = [&](int rows, int circle_samples) {
    long samples = 0;
    for (const scene::Object& o : scene.objects()) {
      if (o.status == scene::TrackStatus::kUninitialised || o.status == scene::TrackStatus::kSearching) continue;
      for (const scene::View& v : o.views) {
        for (const scene::LineFeature& f : v.lines)
          if (f.visible && !f.ambiguous && !f.dropped) samples += rows;
        for (const scene::ArcFeature& a : v.arcs)
          if (a.visible && !a.dropped) samples += std::min(a.samples, circle_samples);
      }
    }
    return static_cast<double>(samples) * cost;
  };
  if (predicted_us(rows_per_line_, samples_per_circle_) <= available_us) return;
  // Level 1: fewer samples per feature (the windows keep their size).
  degrade_level_ = 1;
  rows_per_line_ = std::max(3, p_.budget.reduced_rows);
  samples_per_circle_ = std::max(8, p_.ellipse.max_samples / 2);
  report_.degrade_level = 1;
  if (predicted_us(rows_per_line_, samples_per_circle_) <= available_us) return;
  // Level 2: leave out the least informative features: the shortest projected edges first
  // (ellipses, which constrain several degrees of freedom, count as long as their circumference).
  degrade_level_ = 2;
  report_.degrade_level = 2;
  drop_scores_.clear();
  for (const scene::Object& o : scene.objects()) {
    if (o.status == scene::TrackStatus::kUninitialised || o.status == scene::TrackStatus::kSearching) continue;
    for (const scene::View& v : o.views) {
      for (const scene::LineFeature& f : v.lines)
        if (f.visible && !f.ambiguous) drop_scores_.push_back(static_cast<float>((f.predicted.b - f.predicted.a).norm()));
      for (const scene::ArcFeature& a : v.arcs)
        if (a.visible) drop_scores_.push_back(1e6f);
    }
  }
  const double per_feature = rows_per_line_ * cost;
  const long keep = std::max<long>(static_cast<long>(available_us / std::max(per_feature, 1e-9)), p_.min_lines);
  if (keep >= static_cast<long>(drop_scores_.size())) return;
  std::nth_element(drop_scores_.begin(), drop_scores_.end() - keep, drop_scores_.end());
  const float threshold = *(drop_scores_.end() - keep);
  long to_drop = static_cast<long>(drop_scores_.size()) - keep;
  for (scene::Object& o : scene.objects()) {
    for (scene::View& v : o.views) {
      for (scene::LineFeature& f : v.lines) {
        if (to_drop <= 0) break;
        if (f.visible && !f.ambiguous && static_cast<float>((f.predicted.b - f.predicted.a).norm()) < threshold) {
          f.dropped = true;
          --to_drop;
          ++report_.features_dropped;
        }
      }
    }
  }
}

int VisionCycle::track_features(const model::Model& model, scene::View& view, const scene::Camera& cam,
                                const CameraImage& img, bool first_pass, int search_level) {
  const geometry::PinholeCamera& K = cam.intrinsics;
  const image::ColourView* colour = img.colour.empty() ? nullptr : &img.colour;
  auto& out = edgels_[view.camera];
  int found = 0;
  refound_ = 0;
  // Back-off (see CycleParams::search_backoff_frames): long-missed features wait their turn,
  // spread over the frames by their index.
  const auto backing_off = [&](int frames_missing, std::size_t index) {
    return first_pass && search_level == 0 && p_.search_backoff_frames > 0 &&
           frames_missing >= p_.search_backoff_frames &&
           (frame_ + static_cast<std::int64_t>(index)) % std::max(1, p_.search_backoff_period) != 0;
  };
  for (std::size_t fi = 0; fi < view.lines.size(); ++fi) {
    scene::LineFeature& f = view.lines[fi];
    if (!f.visible || f.ambiguous || f.dropped) continue;
    if (backing_off(f.frames_missing, fi)) {
      f.measurement = features::LineMeasurement{};
      f.retrack = false;
      continue;
    }
    // The first pass measures every feature: features not found in the last frame are searched
    // in the wide window (wider still after bad frames), found ones tracked in the narrow one.
    // Later passes start from the fresh pose and measure again, in the narrow window, only what
    // was missed or rejected: a found edge's line does not depend on where its window sat.
    if (first_pass || f.retrack) {
      f.predicted.a = K.project(view.T_cam_obj * f.X1);
      f.predicted.b = K.project(view.T_cam_obj * f.X2);
      const bool search = first_pass && (f.status != scene::FeatureStatus::kFound || search_level > 0);
      features::LineTracker& t = search ? searchers_[std::min<std::size_t>(search_level, searchers_.size() - 1)]
                                        : (degrade_level_ >= 1 ? reduced_tracker_ : tracker_);
      f.measurement = t.track(img.grey, f.predicted, f.track, colour, f.range);
      if (!first_pass && f.measurement.found) ++refound_;
      last_samples_ += t.params().rows;
      ++report_.windows;
      // Re-measured in a later pass: missed in the narrow window (the fresh pose may bring the
      // edge into it); a miss in the wide search window already covered the narrow one.
      f.retrack = !f.measurement.found && !search;
      if (f.measurement.found) {
        undistorted_line(K, f.measurement, t.last_inliers(), undistorted_, f.line_n1, f.line_n2);
        for (const Eigen::Vector2d& p : t.last_inliers())
          if (out.size() < out.capacity()) out.push_back(p);
      }
    }
    if (f.measurement.found) ++found;
  }
  const Eigen::Matrix3d R = view.T_cam_obj.rotation();
  for (std::size_t ai = 0; ai < view.arcs.size(); ++ai) {
    scene::ArcFeature& a = view.arcs[ai];
    if (!a.visible || a.dropped) continue;
    if (backing_off(a.frames_missing, view.lines.size() + ai)) {
      a.measurement = features::EllipseMeasurement{};
      a.retrack = false;
      a.edges = 0;
      continue;
    }
    if (first_pass || a.retrack) {
      const model::CircleArc& arc = model.arcs()[a.arc];
      const Eigen::Vector3d c_cam = view.T_cam_obj * arc.center;
      const Eigen::Vector3d n_cam = R * arc.normal;
      curve_.clear();
      const int step = a.samples > samples_per_circle_ ? 2 : 1;  // budget: every other line
      for (int k = 0; k < a.samples; k += step) {
        const Eigen::Vector3d P = view.T_cam_obj * a.X[k];
        const Eigen::Vector2d p = K.project(P);
        // Tangent of the circle at X, projected: the normal of the image curve is across it.
        const Eigen::Vector3d t3 = n_cam.cross(P - c_cam).normalized() * 1e-3;
        const Eigen::Vector2d dt = K.project(P + t3) - K.project(P - t3);
        if (dt.norm() < 1e-9) continue;
        const Eigen::Vector2d nrm = Eigen::Vector2d(-dt.y(), dt.x()).normalized();
        curve_.push_back(features::CurveSample{p, nrm});
      }
      const bool search = first_pass && (a.status != scene::FeatureStatus::kFound || search_level > 0);
      features::EllipseTracker& t = search ? ellipse_searcher_ : (degrade_level_ >= 1 ? reduced_ellipse_tracker_ : ellipse_tracker_);
      a.measurement = t.track(img.grey, curve_, a.track);
      if (!first_pass && a.measurement.found) ++refound_;
      last_samples_ += static_cast<long>(curve_.size());
      ++report_.windows;
      a.retrack = !a.measurement.found && !search;
      a.edges = 0;
      if (a.measurement.found) {
        for (const Eigen::Vector2d& p : t.last_inliers()) {
          if (a.edges < scene::ArcFeature::kMaxSamples) a.edge_px[a.edges++] = p;
          if (out.size() < out.capacity()) out.push_back(p);
        }
      }
    }
    if (a.measurement.found) ++found;
  }
  return found;
}

void VisionCycle::add_tangent_junctions(const model::Model& model, const scene::View& view, const scene::Camera& cam) {
  // Junctions where a straight edge runs into a circle arc along its tangent (a slot, a rounded
  // corner): the two image curves touch instead of crossing, so their intersection is undefined.
  // The junction is the point of the measured ellipse whose tangent is parallel to the measured
  // line (of the two, the one nearer the predicted junction); it counts when the line passes
  // within tangent_junction_tol_px of it, i.e. when the two edges agree where they meet.
  constexpr double kTangentCos = 0.996;  // the model edge and the arc's tangent within 5 degrees
  const geometry::PinholeCamera& K = cam.intrinsics;
  const auto& arcs = model.arcs();
  const auto& junctions = model.junctions();
  const auto& lines = model.lines();
  for (const scene::ArcFeature& a : view.arcs) {
    if (!a.visible || a.dropped || !a.measurement.found) continue;
    const model::CircleArc& arc = arcs[a.arc];
    if (arc.end - arc.start >= kTwoPi - 1e-9) continue;  // a full circle has no ends
    const Eigen::Vector3d y_axis = arc.normal.cross(arc.x_axis);
    const double tol = 1e-6 * std::max(1.0, arc.radius);
    for (const double th : {arc.start, arc.end}) {
      const Eigen::Vector3d E = arc.center + arc.radius * (std::cos(th) * arc.x_axis + std::sin(th) * y_axis);
      const Eigen::Vector3d tangent = -std::sin(th) * arc.x_axis + std::cos(th) * y_axis;
      for (std::size_t j = 0; j < junctions.size(); ++j) {
        const model::Junction& J = junctions[j];
        if ((J.p - E).squaredNorm() > tol * tol) continue;
        for (const model::Index li : J.lines) {
          const model::LineEdge& e = lines[li];
          const Eigen::Vector3d dir = (junctions[e.b].p - junctions[e.a].p).normalized();
          if (std::abs(dir.dot(tangent)) < kTangentCos) continue;
          const scene::LineFeature& f = view.lines[li];
          if (!f.visible || f.ambiguous || f.dropped || !f.measurement.found) continue;
          if ((f.X1 - J.p).squaredNorm() > 1e-12 && (f.X2 - J.p).squaredNorm() > 1e-12) continue;  // end hidden
          const Eigen::Vector3d Pj = view.T_cam_obj * J.p;
          if (Pj.z() <= 1e-6) continue;
          const Eigen::Vector2d predicted = K.project(Pj);
          // Tangent point: x(t) = c + a cos t u + b sin t v has x'(t) parallel to d where
          // -a sin t (u x d) + b cos t (v x d) = 0.
          const features::Ellipse2& el = a.measurement.ellipse;
          const Eigen::Vector2d u(std::cos(el.angle), std::sin(el.angle)), v(-u.y(), u.x());
          const Eigen::Vector2d p1 = f.measurement.line.a, p2 = f.measurement.line.b;
          const Eigen::Vector2d d = (p2 - p1).normalized();
          const auto cross = [](const Eigen::Vector2d& x, const Eigen::Vector2d& y) { return x.x() * y.y() - x.y() * y.x(); };
          const double t0 = std::atan2(el.b * cross(v, d), el.a * cross(u, d));
          Eigen::Vector2d best = Eigen::Vector2d::Zero();
          double best_dist = std::numeric_limits<double>::infinity();
          for (const double t1 : {t0, t0 + 0.5 * kTwoPi}) {
            const Eigen::Vector2d x = el.center + el.a * std::cos(t1) * u + el.b * std::sin(t1) * v;
            const double dist = (x - predicted).norm();
            if (dist < best_dist) {
              best_dist = dist;
              best = x;
            }
          }
          if (!(best_dist <= p_.search_half_width)) continue;
          const double gap = std::abs(cross(d, best - p1));  // the line's distance from the tangent point
          if (!(gap <= p_.tangent_junction_tol_px)) continue;
          if (point_obs_.size() >= point_obs_.capacity()) return;  // (capacity: one per junction)
          estimation::PointObservation o;
          o.X_obj = J.p;
          o.xn = K.pixel_to_normalized(best);
          o.sigma_px = p_.line_sigma_px * p_.tangent_junction_sigma_scale;
          point_obs_.push_back(o);
          ++tangent_junctions_;
        }
      }
    }
  }
}

void VisionCycle::collect_observations(const scene::Object& obj, scene::View& view, const scene::Camera& cam) {
  const model::Model& model = *obj.model;
  const geometry::PinholeCamera& K = cam.intrinsics;
  line_obs_.clear();
  line_obs_feature_.clear();
  for (std::size_t i = 0; i < view.lines.size(); ++i) {
    const scene::LineFeature& f = view.lines[i];
    if (!f.visible || f.ambiguous || f.dropped || !f.measurement.found) continue;
    estimation::LineObservation o;
    o.X1_obj = f.X1;
    o.X2_obj = f.X2;
    o.xn1 = f.line_n1;
    o.xn2 = f.line_n2;
    o.sigma_px = f.sigma_px > 0.0 ? f.sigma_px : p_.line_sigma_px;
    line_obs_.push_back(o);
    line_obs_feature_.push_back(static_cast<std::uint32_t>(i));
  }
  line_inlier_.assign(line_obs_.size(), 1);

  // Junctions (paper 3.3): where tracked edges meet at a model junction at a clear angle, their
  // intersection (Foerstner: the intersection of the two measured image lines) is a point
  // observation of the junction. Of several edges, the pair meeting at the largest angle is used.
  point_obs_.clear();
  tangent_junctions_ = 0;
  if (p_.use_junctions) {
    const double sin_min = std::sin(p_.junction_min_angle);
    const auto& junctions = model.junctions();
    add_tangent_junctions(model, view, cam);
    for (std::size_t j = 0; j < junctions.size(); ++j) {
      const model::Junction& J = junctions[j];
      if (J.lines.size() < 2) continue;
      double best_sin = sin_min;
      Eigen::Vector3d best_l1 = Eigen::Vector3d::Zero(), best_l2 = Eigen::Vector3d::Zero();
      bool have = false;
      for (std::size_t u = 0; u < J.lines.size(); ++u) {
        const scene::LineFeature& f = view.lines[J.lines[u]];
        if (!f.visible || f.ambiguous || f.merged || f.dropped || !f.measurement.found) continue;
        if ((f.X1 - J.p).squaredNorm() > 1e-12 && (f.X2 - J.p).squaredNorm() > 1e-12) continue;  // end hidden
        const Eigen::Vector2d du = (f.line_n2 - f.line_n1).normalized();
        for (std::size_t w = u + 1; w < J.lines.size(); ++w) {
          const scene::LineFeature& g = view.lines[J.lines[w]];
          if (!g.visible || g.ambiguous || g.merged || g.dropped || !g.measurement.found) continue;
          if ((g.X1 - J.p).squaredNorm() > 1e-12 && (g.X2 - J.p).squaredNorm() > 1e-12) continue;
          const Eigen::Vector2d dw = (g.line_n2 - g.line_n1).normalized();
          const double sn = std::abs(du.x() * dw.y() - du.y() * dw.x());
          if (sn > best_sin) {
            best_sin = sn;
            best_l1 = line_through(f.line_n1, f.line_n2);
            best_l2 = line_through(g.line_n1, g.line_n2);
            have = true;
          }
        }
      }
      if (!have) continue;
      const Eigen::Vector3d h = best_l1.cross(best_l2);
      if (std::abs(h.z()) < 1e-12) continue;
      const Eigen::Vector2d xn = h.head<2>() / h.z();
      // The intersection must lie where the junction is predicted (else an edge is wrong).
      const Eigen::Vector3d Pj = view.T_cam_obj * J.p;
      if (Pj.z() <= 1e-6 || (K.normalized_to_pixel(xn) - K.project(Pj)).norm() > p_.search_half_width) continue;
      estimation::PointObservation o;
      o.X_obj = J.p;
      o.xn = xn;
      o.sigma_px = p_.line_sigma_px * p_.junction_sigma_scale / best_sin;
      point_obs_.push_back(o);
    }
  }
  point_inlier_.assign(point_obs_.size(), 1);

  // Ellipse edge points: each one observes its model circle (paper 3.2, 5).
  circle_obs_.clear();
  circle_obs_feature_.clear();
  for (std::size_t i = 0; i < view.arcs.size(); ++i) {
    const scene::ArcFeature& a = view.arcs[i];
    if (!a.visible || a.dropped || !a.measurement.found) continue;
    const model::CircleArc& arc = model.arcs()[a.arc];
    // At most circle_max_points evenly spread edge points per ellipse: they constrain the pose
    // as well as all of them would, at a fraction of the solver's cost.
    const int stride = std::max(1, (a.edges + p_.circle_max_points - 1) / std::max(1, p_.circle_max_points));
    for (int k = 0; k < a.edges; k += stride) {
      estimation::CircleObservation o;
      o.center_obj = arc.center;
      o.normal_obj = arc.normal;
      o.radius = arc.radius;
      o.xn = K.pixel_to_normalized(a.edge_px[k]);
      o.sigma_px = p_.circle_sigma_px;
      circle_obs_.push_back(o);
      circle_obs_feature_.push_back(static_cast<std::uint32_t>(i));
    }
  }
  circle_inlier_.assign(circle_obs_.size(), 1);
}

void VisionCycle::process_view(scene::Object& obj, scene::View& view, const scene::Camera& cam,
                               const CameraImage& img, ObjectReport& rep) {
  const geometry::PinholeCamera& K = cam.intrinsics;
  int visible = 0;
  for (const scene::LineFeature& f : view.lines) visible += f.visible && !f.ambiguous && !f.dropped ? 1 : 0;
  for (const scene::ArcFeature& a : view.arcs) visible += a.visible && !a.dropped ? 1 : 0;

  solver_.params() = p_.solver;
  solver_.params().focal_px = K.focal();
  estimation::PoseResult result;
  bool updated = false;
  int found = 0;
  const int passes = std::max(1, p_.refine_passes);
  // The prediction as a prior (see CycleParams::prior_fallback), in this camera's frame.
  const geometry::SE3 T_view_pred = view.T_cam_obj;
  const bool can_prior =
      p_.prior_fallback && obj.confirmed && obj.covariance_pred.allFinite() && obj.covariance_pred.trace() > 0.0;
  view.prior_used = false;
  for (int pass = 0; pass < passes; ++pass) {
    const auto ta = now_();
    found = track_features(*obj.model, view, cam, img, pass == 0, rep.search_level);
    const auto tb = now_();
    report_.track_ms += ms_between(ta, tb);
    // A later pass whose re-measured features all failed again adds nothing: the last solve stands.
    if (pass > 0 && refound_ == 0) break;

    collect_observations(obj, view, cam);
    const int n_obs = static_cast<int>(line_obs_.size() + point_obs_.size() + circle_obs_.size() / 4);
    if (n_obs >= p_.min_lines || (can_prior && n_obs >= 1)) {
      estimation::ObservationSet obs;
      obs.points = point_obs_;
      obs.lines = line_obs_;
      obs.circles = circle_obs_;
      estimation::InlierFlags flags;
      flags.points = point_inlier_;
      flags.lines = line_inlier_;
      flags.circles = circle_inlier_;
      // A solve whose residuals are far above the a-priori noise holds a wrong feature that its
      // few observations cannot single out; the prior's redundancy can.
      result = estimation::PoseResult{};
      if (n_obs >= p_.min_lines) result = solver_.solve(view.T_cam_obj, obs, flags);
      bool with_prior = false;
      if (can_prior && !(result.ok() && result.inliers >= p_.min_lines && result.rms_px <= p_.prior_max_rms_px)) {
        // Partial observability: the image fixes some directions, the prediction the others.
        const geometry::Matrix6d Ad = geometry::adjoint(cam.T_ref_cam.inverse());
        geometry::Matrix6d cov = Ad * obj.covariance_pred * Ad.transpose();
        cov.diagonal().array() += 1e-12;
        prior_.T_cam_obj = T_view_pred;
        prior_.information = cov.inverse();
        obs.prior = &prior_;
        std::fill(line_inlier_.begin(), line_inlier_.end(), 1);
        std::fill(point_inlier_.begin(), point_inlier_.end(), 1);
        std::fill(circle_inlier_.begin(), circle_inlier_.end(), 1);
        result = solver_.solve(T_view_pred, obs, flags);
        with_prior = result.ok();
      }
      if (result.ok() && (with_prior || result.inliers >= p_.min_lines)) {
        view.T_cam_obj = result.T_cam_obj;
        updated = true;
        view.prior_used = with_prior;
        // Information of the observations alone: the solve's, less the prior's (both scaled by
        // the solve's sigma0^2), kept positive semi-definite.
        const double s0 = std::max(result.sigma0, p_.solver.min_sigma0);
        geometry::Matrix6d info = result.covariance.inverse();
        if (with_prior) info -= prior_.information / (s0 * s0);
        info = 0.5 * (info + info.transpose()).eval();
        const Eigen::SelfAdjointEigenSolver<geometry::Matrix6d> es(info);
        geometry::Vector6d ev = es.eigenvalues().cwiseMax(1e-9 * std::max(es.eigenvalues().maxCoeff(), 1e-30));
        view.information = es.eigenvectors() * ev.asDiagonal() * es.eigenvectors().transpose();
      }
      for (std::size_t k = 0; k < line_obs_feature_.size(); ++k)
        if (!line_inlier_[k]) view.lines[line_obs_feature_[k]].retrack = true;
      // An ellipse with many rejected edge points is measured again.
      for (std::size_t k = 0, start = 0; k <= circle_obs_feature_.size(); ++k) {
        if (k < circle_obs_feature_.size() && circle_obs_feature_[k] == circle_obs_feature_[start]) continue;
        if (k > start) {
          int bad = 0;
          for (std::size_t q = start; q < k; ++q) bad += circle_inlier_[q] ? 0 : 1;
          if (2 * bad > static_cast<int>(k - start)) view.arcs[circle_obs_feature_[start]].retrack = true;
        }
        start = k;
      }
    }
    report_.solve_ms += ms_between(tb, now_());
    if (!updated) break;
  }

  // Feature states after the last pass.
  int outliers = 0;
  auto settle = [](auto& f) {
    if (f.measurement.found) {
      f.status = scene::FeatureStatus::kFound;
      f.frames_missing = 0;
    } else {
      if (f.status != scene::FeatureStatus::kNotFound) f.status = scene::FeatureStatus::kLost;
      if (++f.frames_missing >= 2) f.track.polarity = 0;  // the background may have changed side
    }
  };
  for (scene::LineFeature& f : view.lines)
    if (f.visible && !f.ambiguous && !f.dropped) settle(f);
  for (scene::ArcFeature& a : view.arcs)
    if (a.visible && !a.dropped) settle(a);
  int lines_used = 0, circle_used = 0, junctions_used = 0;
  for (std::size_t k = 0; k < line_obs_feature_.size(); ++k) {
    if (line_inlier_[k]) {
      ++lines_used;
      continue;
    }
    scene::LineFeature& f = view.lines[line_obs_feature_[k]];
    f.status = scene::FeatureStatus::kOutlier;
    f.track.polarity = 0;
    ++outliers;
  }
  for (std::uint8_t in : circle_inlier_) {
    circle_used += in;
    outliers += 1 - in;
  }
  for (std::uint8_t in : point_inlier_) {
    junctions_used += in;
    outliers += 1 - in;
  }
  view.pose = result;
  if (!updated) view.pose.status = result.ok() ? estimation::SolveStatus::kTooFewObservations : result.status;

  rep.features_visible += visible;
  rep.features_found += found;
  if (updated) {
    rep.features_used += result.inliers;
    rep.lines_used += lines_used;
    rep.circle_points_used += circle_used;
    rep.junctions_used += junctions_used;
    rep.tangent_junctions += tangent_junctions_;
    rep.outliers += outliers;
    rep.rms_px = result.rms_px;
  }
  rep.iterations += result.iterations;
  measure_evidence(view, cam, img);
}

void VisionCycle::measure_evidence(scene::View& view, const scene::Camera& cam,
                                   const CameraImage& img) {
  // Gradient thresholds: a tracked edge's own (what its window needed against noise and
  // texture), else the lowest of this view's tracked edges, else the evidence test's floor.
  float view_thr = 0.0f;
  for (const scene::LineFeature& f : view.lines)
    if (f.visible && f.measurement.found && f.measurement.threshold > 0.0f)
      view_thr = view_thr > 0.0f ? std::min(view_thr, f.measurement.threshold) : f.measurement.threshold;
  const geometry::PinholeCamera& K = cam.intrinsics;
  const geometry::SE3& T = view.T_cam_obj;
  evidence_.reset();
  for (const scene::LineFeature& f : view.lines) {
    // Every visible edge, tracked or not (ambiguous, left out by the budget); a merged pair's
    // mid-line is no edge of the image.
    if (!f.visible || f.merged) continue;
    const Eigen::Vector3d A = T * f.X1, B = T * f.X2;
    if (A.z() <= 1e-3 || B.z() <= 1e-3) continue;
    const float thr = f.measurement.found && f.measurement.threshold > 0.0f ? f.measurement.threshold : view_thr;
    const Eigen::Vector2d a = K.project(A), b = K.project(B);
    if (!K.has_distortion()) {
      evidence_.add_segment(img.grey, a, b, thr);
      continue;
    }
    const int k = evidence_.samples_for_length((b - a).norm());
    for (int i = 0; i < k; ++i) {  // a straight edge bends under distortion: project each sample
      const double s = (i + 0.5) / k, e = 0.25 / k;
      const Eigen::Vector2d p = K.project(A + s * (B - A));
      const Eigen::Vector2d d = K.project(A + (s + e) * (B - A)) - K.project(A + (s - e) * (B - A));
      if (d.norm() < 1e-9) continue;
      evidence_.add_sample(img.grey, p, Eigen::Vector2d(-d.y(), d.x()).normalized(), thr);
    }
  }
  for (const scene::ArcFeature& a : view.arcs) {
    if (!a.visible || a.samples < 2) continue;
    for (int k = 0; k < a.samples; ++k) {
      const Eigen::Vector3d P = T * a.X[static_cast<std::size_t>(k)];
      const Eigen::Vector3d P0 = T * a.X[static_cast<std::size_t>(std::max(0, k - 1))];
      const Eigen::Vector3d P1 = T * a.X[static_cast<std::size_t>(std::min(a.samples - 1, k + 1))];
      if (P.z() <= 1e-3 || P0.z() <= 1e-3 || P1.z() <= 1e-3) continue;
      const Eigen::Vector2d d = K.project(P1) - K.project(P0);
      if (d.norm() < 1e-9) continue;
      evidence_.add_sample(img.grey, K.project(P), Eigen::Vector2d(-d.y(), d.x()).normalized(), view_thr);
    }
  }
  view.evidence_samples = evidence_.samples();
  view.evidence_matched = evidence_.matched();
}

void VisionCycle::fuse_and_filter(scene::Scene& scene, scene::Object& obj, ObjectReport& rep, double stamp_s) {
  // Fuse the view poses into the object pose: information-weighted mean in the tangent space of
  // the first good view (one view: its pose, moved into the reference frame).
  geometry::SE3 T0_ref;
  bool prior_used = false;
  geometry::Matrix6d info_sum = geometry::Matrix6d::Zero();
  geometry::Vector6d info_xi = geometry::Vector6d::Zero();
  int good = 0;
  for (const scene::View& view : obj.views) {
    if (!view.pose.ok()) continue;
    const scene::Camera& cam = scene.cameras()[view.camera];
    const geometry::SE3 T_ref = cam.T_ref_cam * view.T_cam_obj;
    // Information in the reference frame: Ad(T_cam_ref)^T I Ad(T_cam_ref) (covariances map with
    // Ad(T_ref_cam)).
    const geometry::Matrix6d Ad_inv = geometry::adjoint(cam.T_ref_cam.inverse());
    if (good == 0) T0_ref = T_ref;
    const geometry::Matrix6d info = Ad_inv.transpose() * view.information * Ad_inv;
    prior_used = prior_used || view.prior_used;
    info_sum += info;
    info_xi += info * (T_ref * T0_ref.inverse()).log();
    ++good;
  }
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
  // Whether the measurement is used follows the features: the share of visible features used,
  // lowered by large residuals.
  double ratio = rep.features_visible > 0 ? static_cast<double>(rep.lines_used + rep.junctions_used / 2 +
                                                                 (rep.circle_points_used > 0 ? 1 : 0)) /
                                                rep.features_visible
                                          : 0.0;
  ratio = std::clamp(ratio, 0.0, 1.0);
  const double residual_factor = 1.0 / (1.0 + (rep.rms_px / 1.5) * (rep.rms_px / 1.5));
  bool accept = good > 0 && ratio * residual_factor >= p_.recovery.lost_quality;
  geometry::SE3 T_meas;
  geometry::Matrix6d cov_meas = geometry::Matrix6d::Zero();
  if (accept) {
    cov_meas = info_sum.inverse();
    T_meas = geometry::SE3::exp(cov_meas * info_xi) * T0_ref;
  }
  if (p_.use_filter) {
    if (accept) {
      // A floor on the measurement covariance keeps the filter from trusting a pose more than the
      // renderer-free reality of a camera allows (0.1 mm, 0.02 degrees).
      geometry::Matrix6d floor = geometry::Matrix6d::Zero();
      floor.diagonal() << 1e-8, 1e-8, 1e-8, 1e-7, 1e-7, 1e-7;
      const double chi2 = obj.filter.innovation_chi2(T_meas, cov_meas + floor);
      if (ratio < p_.degraded_ratio && chi2 > p_.recovery.gate_chi2) {
        accept = false;  // a weak measurement far from the prediction: more likely wrong than right
        rep.measurement_rejected = true;
      } else {
        obj.filter.update(T_meas, cov_meas + floor);
        // The reported pose: the smoother's. A measurement it cannot explain even at full noise
        // (a recovery, a jump) restarts it there.
        if (p_.smooth_output && obj.smoother.update(T_meas, cov_meas + floor) > p_.recovery.gate_chi2)
          obj.smoother.reset(T_meas, cov_meas + floor);
      }
    }
  }
  if (accept) {
    obj.T_ref_obj = p_.use_filter && p_.smooth_output && obj.smoother.initialised() ? obj.smoother.pose() : T_meas;
    // Directions held by the prediction carry the filter's covariance, not the (huge) one of
    // the observations alone.
    obj.covariance = prior_used && p_.use_filter ? obj.filter.pose_covariance() : cov_meas;
    obj.measured = ratio >= p_.degraded_ratio && !prior_used ? scene::TrackStatus::kTracking : scene::TrackStatus::kDegraded;
    rep.prior_used = prior_used;
  } else {
    // No usable measurement: hold the prediction (the filter's, which does not run away: its
    // velocity is dropped after a few bad frames) and search wider next time.
    obj.T_ref_obj = obj.T_pred;
    obj.measured = scene::TrackStatus::kLost;
  }
  // The reported status: what the image shows at the pose.
  if (!accept || evidence < p_.status.lost_evidence) {
    obj.status = scene::TrackStatus::kLost;
  } else if (evidence >= p_.status.tracking_evidence && obj.measured == scene::TrackStatus::kTracking) {
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
  if (p_.use_filter) {
    if (!accept && obj.bad_frames >= p_.recovery.reset_velocity_after) {
      obj.filter.reset_velocity();
      obj.smoother.reset_velocity();
    }
    obj.T_ref_obj_filtered = obj.filter.pose();
    obj.velocity = obj.filter.velocity();
  } else {
    obj.T_ref_obj_filtered = obj.T_ref_obj;
    obj.velocity.setZero();
  }
  rep.status = obj.status;
  rep.quality = obj.quality;
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
  report_.frame = frame_++;
  report_.stamp_s = stamp_s;
  report_.visibility_ms = report_.track_ms = report_.solve_ms = 0.0;
  last_samples_ = 0;
  report_.windows = 0;
  for (auto& e : edgels_) e.clear();
  auto& objects = scene.objects();

  // 1. Predict every object and decide what each view can see.
  for (std::size_t oi = 0; oi < objects.size(); ++oi) {
    scene::Object& obj = objects[oi];
    ObjectReport& rep = report_.objects[oi];
    rep = ObjectReport{};
    if (obj.status == scene::TrackStatus::kUninitialised) continue;
    // Issue 10: an object being searched for is left to pipeline::ObjectSearch.
    if (obj.status == scene::TrackStatus::kSearching) {
      rep.status = obj.status;
      continue;
    }
    // One object's fault (a bug, bad_alloc, an OpenCV exception) must not end the others' cycle.
    try {
      rep.search_level = std::min(obj.bad_frames, p_.recovery.max_search_level);
      const double dt = obj.last_stamp >= 0.0 ? std::max(0.0, stamp_s - obj.last_stamp) : 0.0;
      // The filter predicts while the object is tracked, and through degraded frames once its
      // motion has been measured; a lost object, or a fresh start pose (whose first correction
      // is no motion), is held.
      // The filter's time update of this frame, done once here: its pose places the windows and
      // its covariance weighs the prior; the measurement update follows in fuse_and_filter.
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
      for (scene::View& view : obj.views) {
        if (view.camera >= images.size() || images[view.camera].grey.empty()) continue;
        predict_view(obj, view, scene.cameras()[view.camera]);
      }
    } catch (const std::exception& e) {
      object_failed(obj, rep, e.what());
    } catch (...) {
      object_failed(obj, rep, "unknown exception");
    }
  }
  const auto t1 = now_();
  report_.visibility_ms = ms_between(t0, t1);

  // 2. Keep the time budget: fewer samples, then fewer features.
  plan_budget(scene);

  // 3. Measure and solve every view; 4. fuse views and filter.
  for (std::size_t oi = 0; oi < objects.size(); ++oi) {
    scene::Object& obj = objects[oi];
    ObjectReport& rep = report_.objects[oi];
    if (obj.status == scene::TrackStatus::kUninitialised || obj.status == scene::TrackStatus::kSearching) continue;
    try {
      if (object_hook_) object_hook_(obj);
      for (scene::View& view : obj.views) {
        if (view.camera >= images.size() || images[view.camera].grey.empty()) {
          view.pose.status = estimation::SolveStatus::kTooFewObservations;
          continue;
        }
        process_view(obj, view, scene.cameras()[view.camera], images[view.camera], rep);
      }
      const auto tf = now_();
      fuse_and_filter(scene, obj, rep, stamp_s);
      report_.solve_ms += ms_between(tf, now_());
    } catch (const std::exception& e) {
      object_failed(obj, rep, e.what());
    } catch (...) {
      object_failed(obj, rep, "unknown exception");
    }
  }

  // Learn the cost of a sample for the next budget decision.
  if (p_.budget.adapt && last_samples_ > 0 && report_.track_ms > 0.0) {
    const double measured = report_.track_ms * 1000.0 / static_cast<double>(last_samples_);
    p_.budget.cost_per_sample_us = 0.8 * p_.budget.cost_per_sample_us + 0.2 * measured;
  }
  report_.cycle_ms = ms_between(t0, now_());
  if (p_.budget.cycle_ms > 0.0 && report_.cycle_ms > p_.budget.cycle_ms) ++report_.overruns;
  return report_;
}

}  // namespace v4r::pipeline
