// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/sample_refinement.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "v4r/geometry/se3_jacobians.hpp"

namespace v4r::pipeline {

namespace {

constexpr int kMinSamples = 12;
constexpr double kCosAligned = 0.92388;  // cos 22.5 deg: a gradient this close to the normal is aligned

/// Sobel gradient at an inside pixel (x in 1..w-2, y in 1..h-2), 8x grey levels per pixel.
inline void sobel(const image::ImageView& g, int x, int y, int& gx, int& gy) {
  const std::uint8_t* r1 = g.data + static_cast<long>(y) * g.stride + x;
  const std::uint8_t* r0 = r1 - g.stride;
  const std::uint8_t* r2 = r1 + g.stride;
  gx = (r0[1] + 2 * r1[1] + r2[1]) - (r0[-1] + 2 * r1[-1] + r2[-1]);
  gy = (r2[-1] + 2 * r2[0] + r2[1]) - (r0[-1] + 2 * r0[0] + r0[1]);
}

/// Nearest pixel of a coordinate; below -0.5 it is 0 or less, which the callers reject anyway
/// (truncation instead of floor: no library call per probe).
inline int round_px(double v) { return static_cast<int>(v + 0.5); }

}  // namespace

void SampleRefiner::reserve() {
  const std::size_t n = static_cast<std::size_t>(std::max(kMinSamples, p_.max_samples));
  if (samples_.capacity() < n) samples_.reserve(n);
}

void SampleRefiner::take_samples(const model::Model& model, std::span<const SampleView> views, const geometry::SE3& T_cam_obj) {
  samples_.clear();
  // A merged pair's feature carries the pair's mid-line: its own model edge is sampled.
  const auto ends = [&](const scene::LineFeature& f, Eigen::Vector3d& X1, Eigen::Vector3d& X2) {
    X1 = f.X1;
    X2 = f.X2;
    if (!f.merged) return;
    if (f.edge >= model.lines().size()) return;
    const model::LineEdge& e = model.lines()[f.edge];
    if (e.a >= model.junctions().size() || e.b >= model.junctions().size()) return;
    X1 = model.junctions()[e.a].p;
    X2 = model.junctions()[e.b].p;
  };
  // max_samples over all views, an equal share each (a second camera costs no more per iteration).
  const std::size_t per_view = samples_.capacity() / std::max<std::size_t>(1, views.size());
  Eigen::Vector3d X1, X2;
  for (std::size_t vi = 0; vi < views.size(); ++vi) {
    const scene::View& view = *views[vi].view;
    const geometry::PinholeCamera& K = *views[vi].K;
    const geometry::SE3 T = views[vi].T_cam_first * T_cam_obj;
    const std::size_t cap = samples_.size() + per_view;
    // The projected length of what is sampled, for the spacing that keeps to max_samples.
    double total = 0.0;
    for (const scene::LineFeature& f : view.lines) {
      if (!f.visible) continue;
      ends(f, X1, X2);
      const Eigen::Vector3d A = T * X1, B = T * X2;
      if (A.z() > 1e-3 && B.z() > 1e-3) total += (K.project(B) - K.project(A)).norm();
    }
    for (const scene::ArcFeature& a : view.arcs)
      if (a.visible && !a.dropped) total += static_cast<double>(a.samples) * p_.spacing_px;
    if (!(total > 0.0) || per_view == 0) continue;
    const double spacing = std::max(p_.spacing_px, total / static_cast<double>(per_view));
    const auto add = [&](const Eigen::Vector3d& X, const Eigen::Vector2d& d) {
      if (samples_.size() >= cap || !(d.norm() > 1e-9)) return;
      samples_.push_back(Sample{X, Eigen::Vector2d(-d.y(), d.x()).normalized(), vi});
    };
    for (const scene::LineFeature& f : view.lines) {
      if (!f.visible) continue;
      ends(f, X1, X2);
      const Eigen::Vector3d A = T * X1, B = T * X2;
      if (!(A.z() > 1e-3 && B.z() > 1e-3)) continue;
      const double len = (K.project(B) - K.project(A)).norm();
      if (!std::isfinite(len)) continue;
      const int k = std::max(1, static_cast<int>(len / spacing));
      for (int i = 0; i < k; ++i) {
        const double s = (i + 0.5) / k, e = 0.25 / k;
        // The direction from the projections either side (a straight edge bends under distortion).
        const Eigen::Vector2d d = K.project(A + (s + e) * (B - A)) - K.project(A + (s - e) * (B - A));
        add(X1 + s * (X2 - X1), d);
      }
    }
    for (const scene::ArcFeature& a : view.arcs) {
      if (!a.visible || a.dropped || a.samples < 2) continue;
      for (int k = 0; k < a.samples; ++k) {
        const auto at = [&](int i) { return a.X[static_cast<std::size_t>(std::clamp(i, 0, a.samples - 1))]; };
        const Eigen::Vector3d P0 = T * at(k - 1), P1 = T * at(k + 1);
        if (!(P0.z() > 1e-3 && P1.z() > 1e-3)) continue;
        add(at(k), K.project(P1) - K.project(P0));
      }
    }
  }
}

double SampleRefiner::search(const image::ImageView& g, const Eigen::Vector2d& px, const Eigen::Vector2d& n, double min_sobel2) const {
  constexpr int kMaxSteps = 32;  // samples.range's bound
  const int steps = std::min(static_cast<int>(p_.range_px), kMaxSteps);
  // |gradient . n| at each offset (NaN outside the image), kept for the sub-pixel place.
  double dots[2 * kMaxSteps + 3];
  const auto along = [&](int k, double& m2) {
    const int x = round_px(px.x() + k * n.x()), y = round_px(px.y() + k * n.y());
    if (x < 1 || y < 1 || x >= g.width - 1 || y >= g.height - 1) return std::numeric_limits<double>::quiet_NaN();
    int gx, gy;
    sobel(g, x, y, gx, gy);
    m2 = static_cast<double>(gx) * gx + static_cast<double>(gy) * gy;
    return std::abs(gx * n.x() + gy * n.y());
  };
  double best = 0.0;
  int best_k = 0;
  bool found = false;
  const double half_per_step = 0.5 / (steps + 1.0);
  for (int k = -steps; k <= steps; ++k) {
    double m2 = 0.0;
    const double dot = along(k, m2);
    dots[k + steps + 1] = dot;
    if (std::isnan(dot) || m2 < min_sobel2 || dot * dot < kCosAligned * kCosAligned * m2) continue;
    // The strongest aligned gradient, nearer ones preferred a little.
    const double s = dot * (1.0 - half_per_step * std::abs(k));
    if (s > best) {
      best = s;
      best_k = k;
      found = true;
    }
  }
  if (!found) return std::numeric_limits<double>::quiet_NaN();
  // The neighbours either side of the best offset: from the scan, or one probe beyond its ends.
  double m2 = 0.0;
  const double v0 = best_k > -steps ? dots[best_k + steps] : along(best_k - 1, m2);
  const double v1 = dots[best_k + steps + 1];
  const double v2 = best_k < steps ? dots[best_k + steps + 2] : along(best_k + 1, m2);
  if (std::isnan(v0) || std::isnan(v2)) return best_k;
  const double denom = v0 - 2.0 * v1 + v2;
  if (!(denom < -1e-9) || v0 > v1 || v2 > v1) return best_k;
  return best_k + std::clamp(0.5 * (v0 - v2) / denom, -0.5, 0.5);
}

bool SampleRefiner::refine(const model::Model& model, const scene::View& view, const geometry::PinholeCamera& K, const image::ImageView& grey,
                           double threshold, geometry::SE3& T_cam_obj) {
  const SampleView one{&view, &K, grey, threshold, geometry::SE3{}};
  return refine(model, std::span<const SampleView>(&one, 1), T_cam_obj);
}

bool SampleRefiner::refine(const model::Model& model, std::span<const SampleView> views, geometry::SE3& T_cam_obj) {
  n_ = 0;
  iterations_ = 0;
  views = views.first(std::min(views.size(), kMaxViews));
  if (views.empty() || !(p_.range_px >= 1.0)) return false;
  for (const SampleView& v : views)
    if (v.view == nullptr || v.K == nullptr || v.grey.empty()) return false;
  take_samples(model, views, T_cam_obj);
  n_ = samples_.size();
  if (n_ < static_cast<std::size_t>(kMinSamples)) return false;
  // Per view: the squared Sobel threshold (Sobel is 8x the gradient), and the pose in its camera
  // once per iteration (a matrix, not a quaternion per sample).
  std::array<double, kMaxViews> min_sobel2{};
  std::array<Eigen::Matrix3d, kMaxViews> R;
  std::array<Eigen::Vector3d, kMaxViews> t;
  // A left step of the first camera's pose is the step Ad(T_cam_first) * delta in this camera's.
  std::array<geometry::Matrix6d, kMaxViews> Ad;
  for (std::size_t vi = 0; vi < views.size(); ++vi) {
    min_sobel2[vi] = 64.0 * views[vi].threshold * views[vi].threshold;
    Ad[vi] = geometry::adjoint(views[vi].T_cam_first);
  }
  const double tukey = p_.range_px;
  geometry::SE3 T = T_cam_obj;
  bool moved = false;
  for (int it = 0; it < p_.iterations; ++it) {
    geometry::Matrix6d H = geometry::Matrix6d::Zero();
    geometry::Vector6d b = geometry::Vector6d::Zero();
    int used = 0;
    for (std::size_t vi = 0; vi < views.size(); ++vi) {
      const geometry::SE3 Tv = vi == 0 ? T : views[vi].T_cam_first * T;
      R[vi] = Tv.rotation();
      t[vi] = Tv.translation();
    }
    for (const Sample& s : samples_) {
      const std::size_t vi = s.view;
      const Eigen::Vector3d Xc = R[vi] * s.X_obj + t[vi];
      const double z = Xc.z();
      if (!(z > 1e-6)) continue;
      const geometry::PinholeCamera& K = *views[vi].K;
      const double r = search(views[vi].grey, K.project(Xc), s.normal, min_sobel2[vi]);
      if (std::isnan(r)) continue;
      const double u = r / tukey;
      if (std::abs(u) >= 1.0) continue;
      const double w = (1.0 - u * u) * (1.0 - u * u);
      geometry::Vector6d J = geometry::normal_motion_jacobian(Xc, s.normal, K.fx, K.fy);
      if (vi != 0) J = (Ad[vi].transpose() * J).eval();  // w.r.t. the first camera's step
      // Residual: the projected sample minus the edge found along n.
      H.noalias() += w * J * J.transpose();
      b.noalias() -= w * r * J;
      ++used;
    }
    if (used < kMinSamples) break;
    H.diagonal() *= 1.0 + 1e-3;
    H.diagonal().array() += 1e-9;
    const geometry::Vector6d delta = H.ldlt().solve(-b);
    if (!delta.allFinite()) break;
    T = geometry::SE3::exp(delta) * T;
    moved = true;
    ++iterations_;
    // Converged when the step moves the model by less than converged_px in every view's image
    // (the search's pixel grid leaves a jitter of a tenth of a pixel or so).
    double move_px = 0.0;
    for (std::size_t vi = 0; vi < views.size(); ++vi) {
      const geometry::SE3 Tv = vi == 0 ? T : views[vi].T_cam_first * T;
      const geometry::Vector6d step = vi == 0 ? delta : geometry::Vector6d(Ad[vi] * delta);
      const Eigen::Vector3d v = step.head<3>(), w = step.tail<3>();
      const double z = std::max(std::abs(Tv.translation().z()), 1e-3);
      move_px = std::max(move_px, views[vi].K->focal() * (w.norm() + v.norm() / z));
    }
    if (move_px < p_.converged_px) break;
  }
  if (!moved || !T.translation().allFinite()) return false;
  T_cam_obj = T;
  return true;
}

}  // namespace v4r::pipeline
