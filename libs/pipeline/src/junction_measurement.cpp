// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/junction_measurement.hpp"

#include <cmath>
#include <limits>

namespace v4r::pipeline {

namespace {

constexpr double kTwoPi = 6.283185307179586;

/// Homogeneous image line through two normalised points.
Eigen::Vector3d line_through(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return Eigen::Vector3d(a.x(), a.y(), 1.0).cross(Eigen::Vector3d(b.x(), b.y(), 1.0));
}

}  // namespace

void JunctionMeasurement::observations(const model::Model& model, const scene::View& view, const scene::Camera& cam,
                                       std::uint8_t camera, ObservationBuffer& out) const {
  const geometry::PinholeCamera& K = cam.intrinsics;
  // Junctions (paper 3.3): where tracked edges meet at a model junction at a clear angle, their
  // intersection (Foerstner: the intersection of the two measured image lines) is a point
  // observation of the junction. Of several edges, the pair meeting at the largest angle is used.
  if (!p_.use_junctions) return;
  const double sin_min = std::sin(p_.junction_min_angle);
  const auto& junctions = model.junctions();
  tangent_junctions(model, view, cam, camera, out);
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
    o.camera = camera;
    if (out.points.size() >= out.points.capacity()) return;
    out.points.push_back(o);
  }
}

void JunctionMeasurement::tangent_junctions(const model::Model& model, const scene::View& view, const scene::Camera& cam,
                                            std::uint8_t camera, ObservationBuffer& out) const {
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
          if (out.points.size() >= out.points.capacity()) return;  // (capacity: one per junction and view)
          estimation::PointObservation o;
          o.X_obj = J.p;
          o.xn = K.pixel_to_normalized(best);
          o.sigma_px = p_.line_sigma_px * p_.tangent_junction_sigma_scale;
          o.camera = camera;
          out.points.push_back(o);
          ++out.tangent_junctions;
        }
      }
    }
  }
}

}  // namespace v4r::pipeline
