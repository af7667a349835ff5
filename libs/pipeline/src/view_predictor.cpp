// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/view_predictor.hpp"

#include "v4r/model/face_centroid.hpp"

#include <algorithm>
#include <cmath>

namespace v4r::pipeline {

namespace {

constexpr double kTwoPi = 6.283185307179586;

}  // namespace

void ViewPredictor::predict(const scene::Object& obj, scene::View& view, const scene::Camera& cam) {
  const model::Model& model = *obj.model;
  const geometry::PinholeCamera& K = cam.intrinsics;
  view.T_cam_obj = cam.T_ref_cam.inverse() * obj.T_pred;

  // Visibility and the visible part of every edge.
  if (edge_vis_.size() < model.lines().size()) edge_vis_.resize(model.lines().size());
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
  if (side_face_.size() < 2 * view.lines.size()) side_face_.resize(2 * view.lines.size());
  for (std::size_t li = 0; li < view.lines.size(); ++li) {
    scene::LineFeature& f = view.lines[li];
    side_face_[2 * li] = side_face_[2 * li + 1] = model::kNone;
    if (!f.visible || f.ambiguous) continue;
    const model::LineEdge& e = model.lines()[f.edge];
    const Eigen::Vector2d a = f.predicted.a, d = f.predicted.b - f.predicted.a;
    const Eigen::Vector2d n(-d.y(), d.x());
    bool side[2] = {false, false};
    for (const model::Index fi : {e.face_left, e.face_right}) {
      if (fi == model::kNone || !view.face_visible[fi]) continue;
      const Eigen::Vector3d pc = view.T_cam_obj * model::face_centroid(model, fi);
      if (pc.z() <= 1e-6) continue;
      const int k = n.dot(K.project(pc) - a) > 0 ? 1 : 0;
      side[k] = true;
      side_face_[2 * li + k] = fi;
    }
    f.track.side[0].is_object = side[0];
    f.track.side[1].is_object = side[1];
  }
  // An object side of an edge not found in the last frame (coming into view, lost, or never
  // found) is searched with the colour learned on the same face by an edge that was found: what
  // it learned before may be stale or learned from a wrong edge (track.share_face_appearance).
  if (p_.share_face_appearance) {
    const std::size_t n_lines = view.lines.size();
    for (std::size_t li = 0; li < n_lines; ++li) {
      scene::LineFeature& f = view.lines[li];
      for (int k = 0; k < 2; ++k) {
        const model::Index face = side_face_[2 * li + k];
        features::SideAppearance& a = f.track.side[k];
        if (face == model::kNone || (a.learned && f.status == scene::FeatureStatus::kFound)) continue;
        for (std::size_t gi = 0; gi < n_lines; ++gi) {
          const scene::LineFeature& g = view.lines[gi];
          if (gi == li || g.status != scene::FeatureStatus::kFound) continue;
          const int gk = side_face_[2 * gi] == face ? 0 : (side_face_[2 * gi + 1] == face ? 1 : -1);
          if (gk < 0) continue;
          const features::SideAppearance& b = g.track.side[gk];
          if (!b.learned || b.channels != 3) continue;  // colour only: a face's chromaticity, not its shading
          a = b;
          a.is_object = true;
          break;
        }
      }
    }
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

void ViewPredictor::leave_out_converging(scene::LineFeature& f, scene::LineFeature& g, double flen, double glen) const {
  scene::LineFeature& shorter = flen <= glen ? f : g;
  const scene::LineFeature& longer = flen <= glen ? g : f;
  const double slen = std::min(flen, glen);
  // A shared junction: one end of each at the same place in the image.
  const auto near = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return (a - b).squaredNorm() < 1.0; };
  const features::Segment2& s = shorter.predicted;
  const features::Segment2& l = longer.predicted;
  if (!(near(s.a, l.a) || near(s.a, l.b) || near(s.b, l.a) || near(s.b, l.b))) return;
  const Eigen::Vector2d su = (s.b - s.a) / slen;
  const Eigen::Vector2d lu = (l.b - l.a).normalized();
  const double sin_angle = std::abs(su.x() * lu.y() - su.y() * lu.x());
  if (slen * sin_angle <= p_.converging_px) shorter.ambiguous = true;
}

void ViewPredictor::mark_ambiguous(scene::View& view, const scene::Camera& cam) const {
  // Two visible edges that project (almost) parallel, side by side and closer than a tracking
  // window is wide (a thin face seen obliquely, a double contour) would both find the stronger
  // edge in their windows. Their windows are split half way between them (each searches only
  // its own side); when that leaves less than split_min_px towards the other edge, the pair is
  // tracked as one: the visible one (the first of two) is measured against the pair's mid-line
  // with a sigma widened by half their separation, and the other is left out (a thin plate's
  // two edges, a face seen edge-on whose far edge runs along the silhouette). A third edge
  // beside such a pair leaves all of them out, unless it is hidden (a grazing face's edge,
  // which only widens the pair's sigma).
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
      if (glen < 1e-9) continue;
      if (std::abs(fu.dot(gd) / glen) < cos_parallel) {
        if (p_.converging_px > 0.0 && f.visible && g.visible) leave_out_converging(f, g, flen, glen);
        continue;
      }
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
          // A hidden edge of a face seen at a grazing angle (a sliver at most) does not crowd a
          // pair: the pair's edge stays, its sigma widened to cover it. (Left out with it, a
          // cube's silhouette went with the far edges of its side face turning edge-on.)
          if (keep.visible && !keep.ambiguous && !other.visible) {
            keep.sigma_px = std::max(keep.sigma_px, p_.line_sigma_px + 0.5 * std::abs(&keep == &f ? s_g : s_f));
            continue;
          }
          f.ambiguous = f.ambiguous || f.visible;  // a third edge in the pair: too crowded
          g.ambiguous = g.ambiguous || g.visible;
          continue;
        }
        // Mid-line: keep's ends moved half way to their closest points on the other's line.
        const Eigen::Vector3d o1 = other.X1, ou = (other.X2 - other.X1).normalized();
        const auto mid = [&](const Eigen::Vector3d& X) { return 0.5 * (X + o1 + ou * ou.dot(X - o1)); };
        // A thin face between them (a plate's edge face: their distance in the model a small
        // share of their length) shows as a bar whose two edges the window finds as a pair; a
        // wide face seen edge-on (a box's side) is no such bar, its texture is no second edge.
        const Eigen::Vector3d kc = 0.5 * (keep.X1 + keep.X2);
        const double apart = (kc - o1 - ou * ou.dot(kc - o1)).norm();
        const double length = std::min((keep.X2 - keep.X1).norm(), (other.X2 - other.X1).norm());
        const bool thin = apart <= p_.pair_thin * length;
        keep.X1 = mid(keep.X1);
        keep.X2 = mid(keep.X2);
        keep.merged = true;
        keep.sigma_px = p_.line_sigma_px + 0.5 * std::abs(s_g);
        keep.range = features::SearchRange{};
        if (p_.pair_span_px > 0.0 && thin) keep.range.pair_span = std::max(p_.pair_span_px, std::abs(s_g) + 2.0);
        other.ambiguous = other.ambiguous || other.visible;
      }
    }
  }
}

}  // namespace v4r::pipeline
