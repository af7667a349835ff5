// v4r - robust model-based object tracking. MIT licence.
#include "v4r/model/model.hpp"

#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <fmt/format.h>

namespace v4r::model {
namespace {

/// Unit normal of the least-squares plane through `centroid` of the loop's points (the
/// eigenvector of their scatter matrix with the smallest eigenvalue), on the side of `orient`.
Eigen::Vector3d least_squares_plane_normal(const std::vector<Junction>& junctions, const std::vector<Index>& loop,
                                           const Eigen::Vector3d& centroid, const Eigen::Vector3d& orient) {
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (Index j : loop) {
    const Eigen::Vector3d d = junctions[j].p - centroid;
    scatter += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  Eigen::Vector3d n = eig.eigenvectors().col(0);  // eigenvalues in increasing order
  if (eig.info() != Eigen::Success || !n.allFinite()) n = orient;
  n.normalize();
  return n.dot(orient) < 0.0 ? Eigen::Vector3d(-n) : n;
}

}  // namespace

Index ModelBuilder::add_junction(const Eigen::Vector3d& p, Attributes attr) {
  Junction j;
  j.p = p;
  j.attr = std::move(attr);
  m_.junctions_.push_back(std::move(j));
  return static_cast<Index>(m_.junctions_.size() - 1);
}

Index ModelBuilder::add_line(Index a, Index b, Attributes attr) {
  if (a < m_.junctions_.size()) {
    for (Index li : m_.junctions_[a].lines) {
      const LineEdge& e = m_.lines_[li];
      if ((e.a == a && e.b == b) || (e.a == b && e.b == a)) {
        if (m_.lines_[li].attr.name.empty()) m_.lines_[li].attr.name = attr.name;
        return li;
      }
    }
  }
  LineEdge e;
  e.a = a;
  e.b = b;
  e.attr = std::move(attr);
  m_.lines_.push_back(std::move(e));
  const auto idx = static_cast<Index>(m_.lines_.size() - 1);
  if (a < m_.junctions_.size()) m_.junctions_[a].lines.push_back(idx);
  if (b < m_.junctions_.size() && b != a) m_.junctions_[b].lines.push_back(idx);
  return idx;
}

Expected<Index> ModelBuilder::add_face(const std::vector<Index>& loop, Attributes attr, double planarity_tol,
                                       FaceEdges edges) {
  if (loop.size() < 3) return make_error(fmt::format("a face needs at least 3 points, got {}", loop.size()));
  for (Index j : loop) {
    if (j >= m_.junctions_.size())
      return make_error(fmt::format("face refers to point {} but only {} points exist", j, m_.junctions_.size()));
  }
  // The face's least-squares plane: through the centroid, normal along the smallest principal
  // axis of the points, oriented like Newell's normal (i.e. by the CCW order of the loop).
  Eigen::Vector3d newell = Eigen::Vector3d::Zero();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < loop.size(); ++i) {
    const Eigen::Vector3d& p = m_.junctions_[loop[i]].p;
    const Eigen::Vector3d& q = m_.junctions_[loop[(i + 1) % loop.size()]].p;
    newell += p.cross(q);
    centroid += p;
  }
  centroid /= static_cast<double>(loop.size());
  if (newell.norm() < 1e-12) return make_error("face is degenerate (zero area)");
  const Eigen::Vector3d n = least_squares_plane_normal(m_.junctions_, loop, centroid, newell);
  for (Index j : loop) {
    const double d = std::abs(n.dot(m_.junctions_[j].p - centroid));
    if (d > planarity_tol)
      return make_error(fmt::format("face is not planar: point {} is {:.6f} m off its plane", j, d));
  }
  Face f;
  f.loop = loop;
  f.normal = n;
  f.attr = std::move(attr);
  m_.faces_.push_back(std::move(f));
  const auto fi = static_cast<Index>(m_.faces_.size() - 1);
  if (edges == FaceEdges::kSkip) return fi;
  for (std::size_t i = 0; i < loop.size(); ++i) {
    const Index li = add_line(loop[i], loop[(i + 1) % loop.size()]);
    LineEdge& e = m_.lines_[li];
    if (e.face_left == kNone) {
      e.face_left = fi;
    } else if (e.face_right == kNone && e.face_left != fi) {
      e.face_right = fi;
    }
  }
  return fi;
}

Expected<void> ModelBuilder::set_line_faces(Index line, Index face_left, Index face_right) {
  if (line >= m_.lines_.size())
    return make_error(fmt::format("line {} does not exist ({} lines)", line, m_.lines_.size()));
  for (Index f : {face_left, face_right}) {
    if (f != kNone && f >= m_.faces_.size())
      return make_error(fmt::format("face {} does not exist ({} faces)", f, m_.faces_.size()));
  }
  m_.lines_[line].face_left = face_left;
  m_.lines_[line].face_right = face_right;
  return {};
}

Index ModelBuilder::add_arc(CircleArc arc) {
  arc.normal.normalize();
  Eigen::Vector3d x = arc.x_axis - arc.normal * arc.normal.dot(arc.x_axis);
  if (x.norm() < 1e-9) x = arc.normal.unitOrthogonal();
  arc.x_axis = x.normalized();
  m_.arcs_.push_back(std::move(arc));
  return static_cast<Index>(m_.arcs_.size() - 1);
}

Index ModelBuilder::add_cylinder(const Cylinder& c) {
  m_.cylinders_.push_back(c);
  const Eigen::Vector3d axis = c.p2 - c.p1;
  for (const Eigen::Vector3d& centre : {c.p1, c.p2}) {
    CircleArc rim;
    rim.center = centre;
    rim.normal = axis.norm() > 0 ? Eigen::Vector3d(axis.normalized()) : Eigen::Vector3d::UnitZ();
    rim.x_axis = rim.normal.unitOrthogonal();
    rim.radius = c.radius;
    rim.attr = c.attr;
    add_arc(rim);
  }
  return static_cast<Index>(m_.cylinders_.size() - 1);
}

Expected<Model> ModelBuilder::build() && {
  double r = 0.0;
  for (std::size_t i = 0; i < m_.junctions_.size(); ++i) {
    if (!m_.junctions_[i].p.allFinite()) return make_error(fmt::format("point {} has a non-finite coordinate", i));
    r = std::max(r, m_.junctions_[i].p.norm());
  }
  for (std::size_t i = 0; i < m_.lines_.size(); ++i) {
    const LineEdge& e = m_.lines_[i];
    if (e.a >= m_.junctions_.size() || e.b >= m_.junctions_.size())
      return make_error(fmt::format("line {} refers to a point that does not exist", i));
    if ((m_.junctions_[e.a].p - m_.junctions_[e.b].p).norm() < 1e-9)
      return make_error(fmt::format("line {} has zero length", i));
  }
  for (std::size_t i = 0; i < m_.arcs_.size(); ++i) {
    const CircleArc& a = m_.arcs_[i];
    if (!(a.radius > 0.0) || !a.center.allFinite() || !a.normal.allFinite())
      return make_error(fmt::format("circle {} is degenerate (radius must be > 0)", i));
    r = std::max(r, a.center.norm() + a.radius);
  }
  m_.bounding_radius_ = r;
  return std::move(m_);
}

}  // namespace v4r::model
