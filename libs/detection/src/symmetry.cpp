// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/symmetry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace v4r::detection {

namespace {

bool has_point(const std::vector<Eigen::Vector3d>& pts, const Eigen::Vector3d& q, double tol) {
  for (const auto& p : pts)
    if ((p - q).norm() <= tol) return true;
  return false;
}

}  // namespace

std::vector<geometry::SE3> model_symmetries(const model::Model& model, double tol) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
  Eigen::Vector3d hi = -lo;
  for (const auto& j : model.junctions()) {
    lo = lo.cwiseMin(j.p);
    hi = hi.cwiseMax(j.p);
  }
  const Eigen::Vector3d c = model.junctions().empty() ? Eigen::Vector3d::Zero() : Eigen::Vector3d(0.5 * (lo + hi));
  // Edge end points and mid-points and arc centres stand for the features; cylinders by their axis
  // ends. (Points that only place a circle, such as a .cao circle's two points on its rim, are
  // not features: the circle maps onto itself whatever happens to them.)
  std::vector<Eigen::Vector3d> pts, mids, arcs;
  for (std::size_t i = 0; i < model.lines().size(); ++i) {
    const Eigen::Vector3d a = model.line_point_a(static_cast<model::Index>(i));
    const Eigen::Vector3d b = model.line_point_b(static_cast<model::Index>(i));
    // (Shared end points once; a coarse tol would merge distinct corners, unevenly.)
    if (!has_point(pts, a, std::min(tol, 1e-6))) pts.push_back(a);
    if (!has_point(pts, b, std::min(tol, 1e-6))) pts.push_back(b);
    mids.push_back(0.5 * (a + b));
  }
  // An arc by its centre and the two points a radius along its normal either way (radius and
  // plane), a partial arc also by its ends and middle.
  for (const auto& a : model.arcs()) {
    arcs.push_back(a.center);
    arcs.push_back(a.center + a.radius * a.normal);
    arcs.push_back(a.center - a.radius * a.normal);
    if (a.end - a.start < 2.0 * M_PI - 1e-9) {
      const Eigen::Vector3d y = a.normal.cross(a.x_axis);
      for (const double t : {a.start, 0.5 * (a.start + a.end), a.end})
        arcs.push_back(a.center + a.radius * (std::cos(t) * a.x_axis + std::sin(t) * y));
    }
  }
  std::vector<geometry::SE3> out;
  // The 24 signed permutation matrices with determinant +1.
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& pm : perms)
    for (int s = 0; s < 8; ++s) {
      Eigen::Matrix3d R = Eigen::Matrix3d::Zero();
      for (int r = 0; r < 3; ++r) R(r, pm[r]) = (s >> r) & 1 ? -1.0 : 1.0;
      if (R.determinant() < 0) continue;
      const auto map = [&](const Eigen::Vector3d& p) -> Eigen::Vector3d { return R * (p - c) + c; };
      bool ok = true;
      for (const auto& p : pts) ok = ok && has_point(pts, map(p), tol);
      for (const auto& p : mids) ok = ok && has_point(mids, map(p), tol);
      for (const auto& p : arcs) ok = ok && has_point(arcs, map(p), tol);
      for (std::size_t i = 0; i < model.cylinders().size() && ok; ++i) {
        const auto& y = model.cylinders()[i];
        bool found = false;
        for (const auto& z : model.cylinders()) {
          const bool same = ((map(y.p1) - z.p1).norm() <= tol && (map(y.p2) - z.p2).norm() <= tol) ||
                            ((map(y.p1) - z.p2).norm() <= tol && (map(y.p2) - z.p1).norm() <= tol);
          found = found || (same && std::abs(y.radius - z.radius) <= tol);
        }
        ok = found;
      }
      if (ok) out.emplace_back(R, c - R * c);
    }
  return out;
}

std::vector<geometry::SE3> near_symmetries(const model::Model& model, double relative_tol) {
  std::vector<geometry::SE3> out;
  if (!(relative_tol > 0.0) || model.junctions().empty()) return out;
  Eigen::Vector3d lo = model.junctions().front().p, hi = lo;
  for (const auto& j : model.junctions()) {
    lo = lo.cwiseMin(j.p);
    hi = hi.cwiseMax(j.p);
  }
  const std::vector<geometry::SE3> exact = model_symmetries(model);
  for (const geometry::SE3& S : model_symmetries(model, relative_tol * (hi - lo).norm())) {
    bool is_exact = false;
    for (const geometry::SE3& E : exact) is_exact = is_exact || (S.rotation() - E.rotation()).norm() < 1e-9;
    if (!is_exact) out.push_back(S);
  }
  return out;
}

namespace {

/// The order of symmetric_pose_error and nearest_symmetric: rotation angle (rad) first, then
/// translation (an equivalent pose is both close).
double pose_distance(const geometry::SE3& a, const geometry::SE3& b) {
  return geometry::rotation_angle_between(a, b) + 10.0 * (a.translation() - b.translation()).norm();
}

}  // namespace

PoseError symmetric_pose_error(const geometry::SE3& estimate, const geometry::SE3& truth,
                               const std::vector<geometry::SE3>& symmetries) {
  PoseError best{std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  double best_cost = std::numeric_limits<double>::infinity();
  const auto consider = [&](const geometry::SE3& t) {
    const double cost = pose_distance(estimate, t);
    if (cost < best_cost) {
      best_cost = cost;
      best = PoseError{(estimate.translation() - t.translation()).norm(), geometry::rotation_angle_between(estimate, t)};
    }
  };
  consider(truth);
  for (const auto& S : symmetries) consider(truth * S);
  return best;
}

geometry::SE3 nearest_symmetric(const geometry::SE3& T, const geometry::SE3& reference,
                                const std::vector<geometry::SE3>& symmetries) {
  geometry::SE3 best = T;
  double best_cost = pose_distance(T, reference);
  for (const auto& S : symmetries) {
    const geometry::SE3 TS = T * S;
    const double cost = pose_distance(TS, reference);
    if (cost < best_cost) {
      best_cost = cost;
      best = TS;
    }
  }
  return best;
}

}  // namespace v4r::detection
