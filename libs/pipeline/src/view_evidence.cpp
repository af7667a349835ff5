// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/view_evidence.hpp"

#include <algorithm>

namespace v4r::pipeline {

namespace {

/// Gradient thresholds: a tracked edge's own (what its window needed against noise and texture),
/// else the lowest of this view's tracked edges (view_threshold), else (0) the evidence test's floor.
float line_threshold(const scene::LineFeature& f, float view_thr) {
  return f.measurement.found && f.measurement.threshold > 0.0f ? f.measurement.threshold : view_thr;
}

}  // namespace

float view_threshold(const scene::View& view) {
  float view_thr = 0.0f;
  for (const scene::LineFeature& f : view.lines)
    if (f.visible && f.measurement.found && f.measurement.threshold > 0.0f)
      view_thr = view_thr > 0.0f ? std::min(view_thr, f.measurement.threshold) : f.measurement.threshold;
  return view_thr;
}

void measure_view_evidence(features::EdgeEvidence& evidence, features::SilhouetteContrast* contrast, scene::View& view,
                           const scene::Camera& cam, const CameraImage& img) {
  const float view_thr = view_threshold(view);
  const geometry::PinholeCamera& K = cam.intrinsics;
  const geometry::SE3& T = view.T_cam_obj;
  evidence.reset();
  if (contrast) contrast->reset();
  for (const scene::LineFeature& f : view.lines) {
    // Every visible edge, tracked or not (ambiguous, left out by the budget); a merged pair's
    // mid-line is no edge of the image.
    if (!f.visible || f.merged) continue;
    const Eigen::Vector3d A = T * f.X1, B = T * f.X2;
    if (A.z() <= 1e-3 || B.z() <= 1e-3) continue;
    const float thr = line_threshold(f, view_thr);
    const Eigen::Vector2d a = K.project(A), b = K.project(B);
    if (!((b - a).norm() > 1e-9)) continue;
    // A silhouette edge (the object on one side; an ambiguous edge's sides are not predicted):
    // where the image shows it, the colours on either side are sampled too.
    const bool obj0 = f.track.side[0].is_object, obj1 = f.track.side[1].is_object;
    const bool silhouette = contrast != nullptr && !f.ambiguous && obj0 != obj1;
    const int k = evidence.samples_for_length((b - a).norm());
    for (int i = 0; i < k; ++i) {
      const double s = (i + 0.5) / k, e = 0.25 / k;
      Eigen::Vector2d p = a + s * (b - a), d = b - a;
      if (K.has_distortion()) {  // a straight edge bends under distortion: project each sample
        p = K.project(A + s * (B - A));
        d = K.project(A + (s + e) * (B - A)) - K.project(A + (s - e) * (B - A));
        if (d.norm() < 1e-9) continue;
      }
      // side[1] lies along n = d turned by +90 degrees (features::LineTrackState).
      const Eigen::Vector2d n = Eigen::Vector2d(-d.y(), d.x()).normalized();
      if (evidence.add_sample(img.grey, p, n, thr) && silhouette)
        contrast->add_point(img.grey, img.colour, p, obj0 ? n : Eigen::Vector2d(-n));
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
      evidence.add_sample(img.grey, K.project(P), Eigen::Vector2d(-d.y(), d.x()).normalized(), view_thr);
    }
  }
  view.evidence_samples = evidence.samples();
  view.evidence_matched = evidence.matched();
  view.leak_samples = view.leak_matched = 0;
  if (contrast) {
    contrast->finish();
    view.leak_samples = contrast->samples();
    view.leak_matched = contrast->leaked();
  }
}

}  // namespace v4r::pipeline
