// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/visibility.hpp"

#include "v4r/geometry/polygon.hpp"
#include "v4r/geometry/ray_cylinder.hpp"
#include "v4r/model/face_centroid.hpp"

#include <cmath>

namespace v4r::pipeline {

namespace {

/// Whether face cache `f` (polygon in `poly`) hides the point at p_cam, seen along the ray
/// through its normalised image point q.
template <typename Face>
bool face_hides(const Face& f, const Eigen::Vector2d* poly, const Eigen::Vector2d& q, const Eigen::Vector3d& p_cam,
                double margin = 0.0) {
  if (q.x() < f.lo.x() || q.y() < f.lo.y() || q.x() > f.hi.x() || q.y() > f.hi.y()) return false;
  const double den = f.n_cam.dot(Eigen::Vector3d(q.x(), q.y(), 1.0));
  if (std::abs(den) < 1e-12) return false;
  const double z_face = f.d / den;
  // The face hides the point when it is hit clearly before it along the line of sight.
  if (z_face <= 0.0 || z_face >= p_cam.z() * (1.0 - 1e-4) - 1e-5 - margin) return false;
  return geometry::inside_polygon(q, poly + f.first, f.count);
}

}  // namespace

bool VisibilityTester::occluded(const Eigen::Vector3d& p_cam, model::Index face_a, model::Index face_b) const {
  const Eigen::Vector2d q(p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z());
  for (std::size_t fi = 0; fi < faces_.size(); ++fi) {
    const FaceCache& f = faces_[fi];
    if (!f.usable || fi == face_a || fi == face_b) continue;
    if (face_hides(f, poly_.data(), q, p_cam)) return true;
  }
  for (const FaceCache& f : occluder_faces_)
    if (face_hides(f, occluder_poly_.data(), q, p_cam, p_.occluder_margin)) return true;
  return false;
}

bool VisibilityTester::cylinder_hides(std::span<const CylinderCache> list, const Eigen::Vector3d& p_cam) {
  const double tp = p_cam.norm();
  if (tp < 1e-9) return false;
  const Eigen::Vector3d d = p_cam / tp;  // line of sight, unit
  const double t_max = tp * (1.0 - 1e-4) - 1e-5;
  for (const CylinderCache& c : list)
    if (geometry::ray_hits_cylinder(d, t_max, c.p1, c.axis, c.radius, c.length, c.radius)) return true;
  return false;
}

bool VisibilityTester::hidden_by_cylinder(const Eigen::Vector3d& p_cam) const {
  return cylinder_hides(cylinders_, p_cam) || cylinder_hides(occluder_cylinders_, p_cam);
}

bool VisibilityTester::hidden_by_other_object(const Eigen::Vector3d& p_cam) const {
  if (p_cam.z() <= 1e-6) return false;
  const Eigen::Vector2d q(p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z());
  for (const FaceCache& f : occluder_faces_)
    if (face_hides(f, occluder_poly_.data(), q, p_cam, p_.occluder_margin)) return true;
  return cylinder_hides(occluder_cylinders_, p_cam);
}

void VisibilityTester::cache_face(const model::Model& model, const model::Face& f, const geometry::SE3& T_cam_obj,
                                  const Eigen::Vector3d& cam_in_obj, FaceCache& c, std::vector<Eigen::Vector2d>& poly) {
  const auto& junctions = model.junctions();
  const Eigen::Vector3d p0 = junctions[f.loop[0]].p;
  // Occluder cache: any face facing the camera (strictly) can hide edges behind it.
  c.usable = f.normal.dot(cam_in_obj - p0) > 0.0;
  c.n_cam = T_cam_obj.rotation() * f.normal;
  c.d = c.n_cam.dot(T_cam_obj * p0);
  if (!c.usable) return;
  c.lo = Eigen::Vector2d::Constant(1e300);
  c.hi = Eigen::Vector2d::Constant(-1e300);
  for (std::uint32_t k = 0; k < c.count; ++k) {
    const Eigen::Vector3d pc = T_cam_obj * junctions[f.loop[k]].p;
    if (pc.z() <= 1e-6) {  // faces crossing the camera plane are not used as occluders
      c.usable = false;
      break;
    }
    const Eigen::Vector2d q(pc.x() / pc.z(), pc.y() / pc.z());
    poly[c.first + k] = q;
    c.lo = c.lo.cwiseMin(q);
    c.hi = c.hi.cwiseMax(q);
  }
}

void VisibilityTester::add_cylinders(const model::Model& model, const geometry::SE3& T_cam_obj,
                                     std::vector<CylinderCache>& out) {
  for (const model::Cylinder& cy : model.cylinders()) {
    CylinderCache c;
    c.p1 = T_cam_obj * cy.p1;
    const Eigen::Vector3d p2 = T_cam_obj * cy.p2;
    c.length = (p2 - c.p1).norm();
    if (c.length < 1e-9) continue;
    c.axis = (p2 - c.p1) / c.length;
    c.radius = cy.radius;
    out.push_back(c);
  }
}

void VisibilityTester::clear_occluders() {
  occluder_faces_.clear();
  occluder_poly_.clear();
  occluder_cylinders_.clear();
}

void VisibilityTester::add_occluder(const model::Model& model, const geometry::SE3& T_cam_obj) {
  const Eigen::Vector3d cam_in_obj = -(T_cam_obj.rotation().transpose() * T_cam_obj.translation());
  for (const model::Face& f : model.faces()) {
    if (f.loop.size() < 3) continue;
    FaceCache c;
    c.first = static_cast<std::uint32_t>(occluder_poly_.size());
    c.count = static_cast<std::uint32_t>(f.loop.size());
    occluder_poly_.resize(occluder_poly_.size() + f.loop.size());
    cache_face(model, f, T_cam_obj, cam_in_obj, c, occluder_poly_);
    if (c.usable) occluder_faces_.push_back(c);
    else occluder_poly_.resize(c.first);
  }
  add_cylinders(model, T_cam_obj, occluder_cylinders_);
}

bool VisibilityTester::hidden(const Eigen::Vector3d& p_cam, model::Index face_a, model::Index face_b) const {
  if (p_cam.z() <= 1e-6) return true;
  return occluded(p_cam, face_a, face_b) || hidden_by_cylinder(p_cam);
}

void VisibilityTester::update(const model::Model& model, const geometry::SE3& T_cam_obj,
                              const geometry::PinholeCamera& cam, std::span<std::uint8_t> face_visible,
                              std::span<EdgeVisibility> out) {
  const auto& faces = model.faces();
  const auto& junctions = model.junctions();
  const Eigen::Matrix3d R = T_cam_obj.rotation();
  const Eigen::Vector3d& t = T_cam_obj.translation();
  const Eigen::Vector3d cam_in_obj = -(R.transpose() * t);
  const double cos_appear = std::cos(p_.appear_angle), cos_disappear = std::cos(p_.disappear_angle);
  const double cos_grazing = std::cos(p_.grazing_angle);
  if (grazing_.size() < faces.size()) grazing_.resize(faces.size());

  faces_.resize(faces.size());
  std::size_t total_vertices = 0;
  for (const auto& f : faces) total_vertices += f.loop.size();
  if (poly_.size() < total_vertices) poly_.resize(total_vertices);

  std::uint32_t cursor = 0;
  for (std::size_t fi = 0; fi < faces.size(); ++fi) {
    const model::Face& f = faces[fi];
    FaceCache& c = faces_[fi];
    c.first = cursor;
    c.count = static_cast<std::uint32_t>(f.loop.size());
    cursor += c.count;
    // Face orientation with hysteresis.
    const Eigen::Vector3d centroid = model::face_centroid(model, static_cast<model::Index>(fi));
    const Eigen::Vector3d to_cam = (cam_in_obj - centroid).normalized();
    const double cosang = f.normal.dot(to_cam);
    const bool was = fi < face_visible.size() && face_visible[fi] != 0;
    const bool now = was ? cosang > cos_disappear : cosang > cos_appear;
    if (fi < face_visible.size()) face_visible[fi] = now ? 1 : 0;
    grazing_[fi] = !now && cosang > cos_grazing ? 1 : 0;
    cache_face(model, f, T_cam_obj, cam_in_obj, c, poly_);
  }

  cylinders_.clear();
  cylinders_.reserve(model.cylinders().size());  // allocates once per model size
  add_cylinders(model, T_cam_obj, cylinders_);
  const int n = std::max(2, p_.samples);
  if (static_cast<int>(sample_ok_.size()) < n) sample_ok_.resize(n);
  const auto& lines = model.lines();
  for (std::size_t li = 0; li < lines.size() && li < out.size(); ++li) {
    const model::LineEdge& e = lines[li];
    EdgeVisibility& v = out[li];
    v = EdgeVisibility{};
    // Orientation: an edge bounded by faces is seen when one of them is; a crease between
    // (almost) coplanar faces is no edge at all. Free lines are always candidates.
    const bool has_l = e.face_left != model::kNone, has_r = e.face_right != model::kNone;
    if (has_l || has_r) {
      const bool vl = has_l && face_visible[e.face_left];
      const bool vr = has_r && face_visible[e.face_right];
      if (!vl && !vr) {
        v.grazing = (has_l && grazing_[e.face_left]) || (has_r && grazing_[e.face_right]);
        continue;
      }
      if (has_l && has_r && faces[e.face_left].normal.dot(faces[e.face_right].normal) > std::cos(p_.crease_angle))
        continue;
    }
    const Eigen::Vector3d A = T_cam_obj * junctions[e.a].p;
    const Eigen::Vector3d B = T_cam_obj * junctions[e.b].p;
    // Samples at the centres of n equal pieces; the longest run of visible samples is kept.
    int best_start = -1, best_len = 0, run_start = -1;
    for (int k = 0; k < n; ++k) {
      const double s = (k + 0.5) / n;
      const Eigen::Vector3d P = A + s * (B - A);
      bool ok = P.z() > 1e-3;
      if (ok) ok = cam.in_image(cam.project(P), p_.image_margin);
      if (ok) ok = !occluded(P, e.face_left, e.face_right) && !hidden_by_cylinder(P);
      if (ok) {
        if (run_start < 0) run_start = k;
        if (k - run_start + 1 > best_len) {
          best_len = k - run_start + 1;
          best_start = run_start;
        }
      } else {
        run_start = -1;
      }
    }
    if (best_len == 0) continue;
    // Extend the run to the full edge where it reaches an end sample, and to the half-way point
    // where it is cut. Where another object hides the edge, the cut is found by bisection between
    // the last seen and the first hidden sample centre, so that no window sits on the hidden part
    // and takes the other object's outline for the edge (objects crossing). Cuts by the object's
    // own faces keep the half-way point: there the occluding outline is the model's own edge.
    const auto seen = [&](double s) {
      const Eigen::Vector3d P = A + s * (B - A);
      return P.z() > 1e-3 && cam.in_image(cam.project(P), p_.image_margin) && !occluded(P, e.face_left, e.face_right) &&
             !hidden_by_cylinder(P);
    };
    const auto cut = [&](double in, double out, int k) {
      if (!hidden_by_other_object(A + out * (B - A))) return static_cast<double>(k) / n;  // half way
      for (int it = 0; it < 5; ++it) {
        const double mid = 0.5 * (in + out);
        (seen(mid) ? in : out) = mid;
      }
      return in;
    };
    v.s0 = best_start == 0 ? 0.0 : cut((best_start + 0.5) / n, (best_start - 0.5) / n, best_start);
    v.s1 = best_start + best_len == n ? 1.0
                                      : cut((best_start + best_len - 0.5) / n, (best_start + best_len + 0.5) / n,
                                            best_start + best_len);
    // Clip to the front of the camera and the image by bisection at the ends that are cut.
    const Eigen::Vector2d pa = cam.project(A + v.s0 * (B - A));
    const Eigen::Vector2d pb = cam.project(A + v.s1 * (B - A));
    const bool ends_ok = (A + v.s0 * (B - A)).z() > 1e-3 && (A + v.s1 * (B - A)).z() > 1e-3 &&
                         cam.in_image(pa, 0.0) && cam.in_image(pb, 0.0);
    if (!ends_ok) {
      // Fall back to the sample centres, which are known to be inside.
      v.s0 = (best_start + 0.5) / n;
      v.s1 = (best_start + best_len - 0.5) / n;
    }
    const Eigen::Vector2d qa = cam.project(A + v.s0 * (B - A));
    const Eigen::Vector2d qb = cam.project(A + v.s1 * (B - A));
    v.visible = (qb - qa).norm() >= p_.min_length_px;
  }
}

}  // namespace v4r::pipeline
