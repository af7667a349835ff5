// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/edge_projection.hpp"

#include "v4r/geometry/polygon.hpp"
#include "v4r/geometry/ray_cylinder.hpp"
#include "v4r/model/face_centroid.hpp"

#include <algorithm>
#include <cmath>

namespace v4r::detection {

EdgeProjector::EdgeProjector(const model::Model& model, double crease_angle)
    : model_(model), cos_crease_(std::cos(crease_angle)) {
  faces_.resize(model.faces().size());
  centroids_.reserve(model.faces().size());
  std::size_t nv = 0;
  for (std::size_t fi = 0; fi < model.faces().size(); ++fi) {
    nv += model.faces()[fi].loop.size();
    centroids_.push_back(model::face_centroid(model, static_cast<model::Index>(fi)));
  }
  poly_.resize(nv);
  cyls_.resize(model.cylinders().size());
  // Worst case: every line, every arc and two limbs per cylinder.
  pieces_.reserve(model.lines().size() + model.arcs().size() + 2 * model.cylinders().size());
  piece_len_.reserve(pieces_.capacity());
  piece_lo_.reserve(pieces_.capacity());
  piece_hi_.reserve(pieces_.capacity());
  occluders_.reserve(faces_.size());
}

void EdgeProjector::prepare(const geometry::SE3& T, const geometry::PinholeCamera& cam) {
  const auto& faces = model_.faces();
  const auto& J = model_.junctions();
  const Eigen::Matrix3d R = T.rotation();
  const Eigen::Vector3d cam_obj = -(R.transpose() * T.translation());
  std::uint32_t cursor = 0;
  for (std::size_t fi = 0; fi < faces.size(); ++fi) {
    const model::Face& f = faces[fi];
    FaceCache& c = faces_[fi];
    c.first = cursor;
    c.count = static_cast<std::uint32_t>(f.loop.size());
    cursor += c.count;
    const Eigen::Vector3d p0 = J[f.loop[0]].p;
    c.front = f.normal.dot(cam_obj - p0) > 0.0;
    c.n_cam = R * f.normal;
    c.d = c.n_cam.dot(T * p0);
    c.lo = Eigen::Vector2d::Constant(1e300);
    c.hi = Eigen::Vector2d::Constant(-1e300);
    bool ok = c.front;
    for (std::uint32_t k = 0; k < c.count && ok; ++k) {
      const Eigen::Vector3d pc = T * J[f.loop[k]].p;
      if (pc.z() <= 1e-6) {
        ok = false;
        break;
      }
      const Eigen::Vector2d q(pc.x() / pc.z(), pc.y() / pc.z());
      poly_[c.first + k] = q;
      c.lo = c.lo.cwiseMin(q);
      c.hi = c.hi.cwiseMax(q);
    }
    c.front = ok;
  }
  for (std::size_t ci = 0; ci < cyls_.size(); ++ci) {
    const model::Cylinder& m = model_.cylinders()[ci];
    CylCache& c = cyls_[ci];
    c.p1 = T * m.p1;
    const Eigen::Vector3d p2 = T * m.p2;
    c.length = (p2 - c.p1).norm();
    c.axis = c.length > 0 ? Eigen::Vector3d((p2 - c.p1) / c.length) : Eigen::Vector3d::UnitZ();
    c.radius = m.radius;
  }
  // The pieces to sample (object frame).
  pieces_.clear();
  const auto& lines = model_.lines();
  for (std::size_t li = 0; li < lines.size(); ++li) {
    const model::LineEdge& e = lines[li];
    const bool hl = e.face_left != model::kNone, hr = e.face_right != model::kNone;
    const bool vl = hl && faces_[e.face_left].front, vr = hr && faces_[e.face_right].front;
    if (hl || hr) {
      if (!vl && !vr) continue;
      if (hl && hr && vl && vr && faces[e.face_left].normal.dot(faces[e.face_right].normal) > cos_crease_) continue;
    }
    Piece p;
    p.a = J[e.a].p;
    p.b = J[e.b].p;
    p.face_a = e.face_left;
    p.face_b = e.face_right;
    // A silhouette: exactly one of its faces turned towards the camera.
    p.silhouette = vl != vr;
    if (p.silhouette) p.inside_a = p.inside_b = centroids_[vl ? e.face_left : e.face_right];
    pieces_.push_back(p);
  }
  for (std::size_t ai = 0; ai < model_.arcs().size(); ++ai) {
    Piece p;
    p.arc = static_cast<int>(ai);
    p.face_a = model_.arcs()[ai].face;
    if (p.face_a != model::kNone && !faces_[p.face_a].front) continue;
    pieces_.push_back(p);
  }
  for (std::size_t ci = 0; ci < model_.cylinders().size(); ++ci) {
    const model::Cylinder& m = model_.cylinders()[ci];
    const Eigen::Vector3d d = m.p2 - m.p1;
    const double len = d.norm();
    if (len <= 0 || m.radius <= 0) continue;
    const Eigen::Vector3d a = d / len;
    Eigen::Vector3d w = (cam_obj - m.p1) - (cam_obj - m.p1).dot(a) * a;
    const double D = w.norm();
    if (D <= m.radius * 1.0001) continue;
    w /= D;
    const Eigen::Vector3d wp = a.cross(w);
    const double c = m.radius / D, s = std::sqrt(std::max(0.0, 1.0 - c * c));
    for (const double sign : {-1.0, 1.0}) {
      const Eigen::Vector3d n = c * w + sign * s * wp;
      Piece p;
      p.a = m.p1 + m.radius * n;
      p.b = m.p2 + m.radius * n;
      p.cylinder = static_cast<int>(ci);
      p.silhouette = true;  // the axis is on the object's side
      p.inside_a = m.p1;
      p.inside_b = m.p2;
      pieces_.push_back(p);
    }
  }
}

Eigen::Vector3d EdgeProjector::piece_point(const Piece& pc, double s) const {
  if (pc.arc < 0) return pc.a + s * (pc.b - pc.a);
  const model::CircleArc& a = model_.arcs()[pc.arc];
  const double th = a.start + s * (a.end - a.start);
  const Eigen::Vector3d y = a.normal.cross(a.x_axis);
  return a.center + a.radius * (std::cos(th) * a.x_axis + std::sin(th) * y);
}

void EdgeProjector::collect_occluders(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, model::Index fa,
                                      model::Index fb) {
  occluders_.clear();
  for (std::size_t fi = 0; fi < faces_.size(); ++fi) {
    const FaceCache& f = faces_[fi];
    if (!f.front || fi == fa || fi == fb) continue;
    if (hi.x() < f.lo.x() || hi.y() < f.lo.y() || lo.x() > f.hi.x() || lo.y() > f.hi.y()) continue;
    occluders_.push_back(static_cast<std::uint32_t>(fi));
  }
}

bool EdgeProjector::hidden(const Eigen::Vector3d& p_cam, int own_cylinder) const {
  if (p_cam.z() <= 1e-6) return true;
  const Eigen::Vector2d q(p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z());
  const Eigen::Vector3d ray(q.x(), q.y(), 1.0);
  for (const std::uint32_t fi : occluders_) {
    const FaceCache& f = faces_[fi];
    if (q.x() < f.lo.x() || q.y() < f.lo.y() || q.x() > f.hi.x() || q.y() > f.hi.y()) continue;
    const double den = f.n_cam.dot(ray);
    if (std::abs(den) < 1e-12) continue;
    const double z = f.d / den;
    if (z <= 0.0 || z >= p_cam.z() * (1.0 - 1e-4) - 1e-5) continue;
    if (geometry::inside_polygon(q, poly_.data() + f.first, f.count)) return true;
  }
  const double tp = p_cam.norm();
  const Eigen::Vector3d d = p_cam / tp;
  const double t_max = tp * (1.0 - 1e-3) - 1e-5;
  for (std::size_t ci = 0; ci < cyls_.size(); ++ci) {
    if (static_cast<int>(ci) == own_cylinder) continue;
    const CylCache& c = cyls_[ci];
    if (geometry::ray_hits_cylinder(d, t_max, c.p1, c.axis, c.radius, c.length, c.radius * std::sqrt(1.0 - 1e-3)))
      return true;
  }
  return false;
}

std::size_t EdgeProjector::sample(const geometry::SE3& T, const geometry::PinholeCamera& cam, double spacing_px,
                                  std::span<EdgeSample> out, double margin_px) {
  if (out.empty()) return 0;
  prepare(T, cam);
  T_last_ = T;
  cam_last_ = cam;
  // Projected length of every piece (polyline of 16 segments), to share the samples out, and its
  // box in normalised image coordinates, for the hidden-line test (points in front of the camera;
  // an arc's polyline box grown by the largest gap between its chords and the arc).
  piece_len_.clear();
  piece_lo_.clear();
  piece_hi_.clear();
  double total = 0.0;
  for (const Piece& pc : pieces_) {
    double len = 0.0;
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = Eigen::Vector2d::Constant(-1e300);
    Eigen::Vector3d prev = T * piece_point(pc, 0.0);
    bool behind = false;  // part of the piece is behind the camera: its box is unbounded
    const auto grow = [&](const Eigen::Vector3d& p) {
      if (p.z() <= 1e-6) {
        behind = true;
        return;
      }
      const Eigen::Vector2d q(p.x() / p.z(), p.y() / p.z());
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    };
    grow(prev);
    const int n = pc.arc < 0 ? 1 : 16;
    for (int k = 1; k <= n; ++k) {
      const Eigen::Vector3d cur = T * piece_point(pc, static_cast<double>(k) / n);
      if (prev.z() > 1e-6 && cur.z() > 1e-6) len += (cam.project(cur) - cam.project(prev)).norm();
      grow(cur);
      prev = cur;
    }
    if (pc.arc >= 0) {
      // The arc bulges past its 16-segment polyline by at most r (1 - cos(pi / 16)) of its span.
      const Eigen::Vector2d pad = 0.02 * (hi - lo).cwiseMax(0.0) + Eigen::Vector2d::Constant(1e-9);
      lo -= pad;
      hi += pad;
    }
    if (behind) {
      lo = Eigen::Vector2d::Constant(-1e300);
      hi = Eigen::Vector2d::Constant(1e300);
    }
    piece_len_.push_back(len);
    piece_lo_.push_back(lo);
    piece_hi_.push_back(hi);
    total += len;
  }
  if (total <= 0.0) return 0;
  const double spacing = std::max(spacing_px, total / static_cast<double>(out.size()) * 1.0001);
  const bool bounds = margin_px >= 0.0;
  const bool distorted = cam.has_distortion();
  const Eigen::Matrix3d R = T.rotation();
  std::size_t count = 0;
  for (std::size_t pi = 0; pi < pieces_.size() && count < out.size(); ++pi) {
    const Piece& pc = pieces_[pi];
    const int n = static_cast<int>(piece_len_[pi] / spacing);
    if (n <= 0) continue;
    collect_occluders(piece_lo_[pi], piece_hi_[pi], pc.face_a, pc.face_b);
    // A straight piece wholly in front of the camera: its points interpolated in the camera
    // frame, its projection's tangent from the derivative of the projection along it (a
    // curve's by a small step along it).
    const bool line = pc.arc < 0;
    const Eigen::Vector3d Ca = line ? Eigen::Vector3d(T * pc.a) : Eigen::Vector3d::Zero();
    const Eigen::Vector3d D = line ? Eigen::Vector3d(R * (pc.b - pc.a)) : Eigen::Vector3d::Zero();
    const bool straight = line && Ca.z() > 1e-6 && Ca.z() + D.z() > 1e-6;
    for (int k = 0; k < n && count < out.size(); ++k) {
      const double s = (k + 0.5) / n;
      const Eigen::Vector3d X = piece_point(pc, s);
      const Eigen::Vector3d Xc = straight ? Eigen::Vector3d(Ca + s * D) : Eigen::Vector3d(T * X);
      if (Xc.z() <= 1e-6) continue;
      const Eigen::Vector2d px = cam.project(Xc);
      if (bounds && !cam.in_image(px, margin_px)) continue;
      if (hidden(Xc, pc.cylinder)) continue;
      Eigen::Vector2d tan;
      if (straight) {
        const double iz = 1.0 / Xc.z();
        const Eigen::Vector2d q(Xc.x() * iz, Xc.y() * iz);
        Eigen::Vector2d dq((D.x() - q.x() * D.z()) * iz, (D.y() - q.y() * D.z()) * iz);
        if (distorted) dq = cam.distort_jacobian(q) * dq;
        tan = Eigen::Vector2d(cam.fx * dq.x(), cam.fy * dq.y());
      } else {
        const double ds = 0.25 / std::max(1, n);
        const Eigen::Vector3d Xa = T * piece_point(pc, s - ds), Xb = T * piece_point(pc, s + ds);
        if (Xa.z() <= 1e-6 || Xb.z() <= 1e-6) continue;
        tan = cam.project(Xb) - cam.project(Xa);
      }
      const double tl = tan.norm();
      if (!(tl > 1e-9)) continue;
      tan /= tl;
      EdgeSample& e = out[count++];
      e.p_obj = X;
      e.px = px;
      e.normal = Eigen::Vector2d(-tan.y(), tan.x());
      e.piece = static_cast<std::uint32_t>(pi);
      e.object_side = 0;
      e.inside_extent_px = 0.0F;
    }
  }
  return count;
}

bool EdgeProjector::on_model(const Eigen::Vector2d& q) const {
  for (std::size_t fi = 0; fi < faces_.size(); ++fi) {
    const FaceCache& f = faces_[fi];
    if (!f.front || q.x() < f.lo.x() || q.y() < f.lo.y() || q.x() > f.hi.x() || q.y() > f.hi.y()) continue;
    if (geometry::inside_polygon(q, poly_.data() + f.first, f.count)) return true;
  }
  const Eigen::Vector3d d = Eigen::Vector3d(q.x(), q.y(), 1.0).normalized();
  for (const CylCache& c : cyls_)
    if (geometry::ray_hits_cylinder(d, 1e12, c.p1, c.axis, c.radius, c.length, c.radius)) return true;
  return false;
}

void EdgeProjector::mark_sides(std::span<EdgeSample> samples, double probe_px) const {
  const geometry::SE3& T = T_last_;
  const geometry::PinholeCamera& cam = cam_last_;
  for (EdgeSample& e : samples) {
    e.object_side = 0;
    e.inside_extent_px = 0.0F;
    if (e.piece >= pieces_.size()) continue;
    const Piece& pc = pieces_[e.piece];
    if (!pc.silhouette) continue;
    // The side of the object: towards the front face's centroid, or a limb's axis (at the
    // sample's place along the piece).
    const Eigen::Vector3d Xc = T * e.p_obj;
    if (Xc.z() <= 1e-6) continue;
    const Eigen::Vector3d span = pc.b - pc.a;
    const double s = span.squaredNorm() > 0.0 ? std::clamp((e.p_obj - pc.a).dot(span) / span.squaredNorm(), 0.0, 1.0) : 0.0;
    const Eigen::Vector3d in = T * (pc.inside_a + s * (pc.inside_b - pc.inside_a));
    if (in.z() <= 1e-6) continue;
    const double side = e.normal.dot(cam.project(in) - e.px);
    if (side == 0.0) continue;
    // Beyond the outline: the background, not another part of the model (near and far probe).
    const Eigen::Vector2d q(Xc.x() / Xc.z(), Xc.y() / Xc.z());
    const Eigen::Vector2d out = (side > 0.0 ? -1.0 : 1.0) * e.normal;
    const Eigen::Vector2d step(out.x() / cam.fx, out.y() / cam.fy);
    if (on_model(q + 0.3 * probe_px * step) || on_model(q + probe_px * step)) continue;
    e.object_side = side > 0.0 ? 1 : -1;
    e.inside_extent_px = static_cast<float>(2.0 * std::abs(side));
  }
}

}  // namespace v4r::detection
