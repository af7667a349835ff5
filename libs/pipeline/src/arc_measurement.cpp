// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/arc_measurement.hpp"

#include <algorithm>

namespace v4r::pipeline {

namespace {

features::EllipseTrackerParams ellipse_params(const CycleParams& p, int half_length, int max_samples) {
  features::EllipseTrackerParams e = p.ellipse;
  e.half_length = half_length;
  e.max_samples = max_samples;
  return e;
}

}  // namespace

ArcMeasurement::ArcMeasurement(const CycleParams& p)
    : p_(p),
      tracker_(p.ellipse),
      searcher_(ellipse_params(p, std::max(p.ellipse.half_length, p.search_half_width), p.ellipse.max_samples)),
      reduced_tracker_(ellipse_params(p, p.ellipse.half_length, std::max(8, p.ellipse.max_samples / 2))) {}

void ArcMeasurement::reserve() {
  if (curve_.capacity() < static_cast<std::size_t>(scene::ArcFeature::kMaxSamples))
    curve_.reserve(scene::ArcFeature::kMaxSamples);
}

int ArcMeasurement::track(const model::Model& model, scene::View& view, const scene::Camera& cam,
                          const CameraImage& img, MeasureContext& ctx) {
  const geometry::PinholeCamera& K = cam.intrinsics;
  const Eigen::Matrix3d R = view.T_cam_obj.rotation();
  int found = 0;
  for (std::size_t ai = 0; ai < view.arcs.size(); ++ai) {
    scene::ArcFeature& a = view.arcs[ai];
    if (!a.visible || a.dropped) continue;
    // Back-off as for lines (their indices continue after the view's lines).
    if (ctx.backing_off(a.frames_missing, view.lines.size() + ai, p_.search_backoff_frames, p_.search_backoff_period)) {
      a.measurement = features::EllipseMeasurement{};
      a.retrack = false;
      a.edges = 0;
      continue;
    }
    if (ctx.first_pass || a.retrack) {
      const model::CircleArc& arc = model.arcs()[a.arc];
      const Eigen::Vector3d c_cam = view.T_cam_obj * arc.center;
      const Eigen::Vector3d n_cam = R * arc.normal;
      curve_.clear();
      const int step = a.samples > ctx.samples_per_circle ? 2 : 1;  // budget: every other line
      for (int k = 0; k < a.samples; k += step) {
        const Eigen::Vector3d P = view.T_cam_obj * a.X[static_cast<std::size_t>(k)];
        const Eigen::Vector2d px = K.project(P);
        // Tangent of the circle at X, projected: the normal of the image curve is across it.
        const Eigen::Vector3d t3 = n_cam.cross(P - c_cam).normalized() * 1e-3;
        const Eigen::Vector2d dt = K.project(P + t3) - K.project(P - t3);
        if (dt.norm() < 1e-9) continue;
        const Eigen::Vector2d nrm = Eigen::Vector2d(-dt.y(), dt.x()).normalized();
        curve_.push_back(features::CurveSample{px, nrm});
      }
      const bool search = ctx.first_pass && (a.status != scene::FeatureStatus::kFound || ctx.search_level > 0);
      features::EllipseTracker& t = search ? searcher_ : (ctx.degrade_level >= 1 ? reduced_tracker_ : tracker_);
      a.measurement = t.track(img.grey, curve_, a.track);
      if (!ctx.first_pass && a.measurement.found) ++ctx.refound;
      ctx.samples += static_cast<long>(curve_.size());
      ++ctx.windows;
      a.retrack = !a.measurement.found && !search;
      a.edges = 0;
      if (a.measurement.found) {
        for (const Eigen::Vector2d& e : t.last_inliers()) {
          if (a.edges < scene::ArcFeature::kMaxSamples) a.edge_px[static_cast<std::size_t>(a.edges++)] = e;
          if (ctx.edgels != nullptr && ctx.edgels->size() < ctx.edgels->capacity()) ctx.edgels->push_back(e);
        }
      }
    }
    if (a.measurement.found) ++found;
  }
  return found;
}

void ArcMeasurement::observations(const model::Model& model, const scene::View& view, const scene::Camera& cam,
                                  std::uint16_t view_index, std::uint8_t camera, ObservationBuffer& out) const {
  const geometry::PinholeCamera& K = cam.intrinsics;
  for (std::size_t i = 0; i < view.arcs.size(); ++i) {
    const scene::ArcFeature& a = view.arcs[i];
    if (!a.visible || a.dropped || !a.measurement.found) continue;
    const model::CircleArc& arc = model.arcs()[a.arc];
    // At most circle_max_points evenly spread edge points per ellipse: they constrain the pose
    // as well as all of them would, at a fraction of the solver's cost.
    const int stride = std::max(1, (a.edges + p_.circle_max_points - 1) / std::max(1, p_.circle_max_points));
    for (int k = 0; k < a.edges; k += stride) {
      if (out.circles.size() >= out.circles.capacity()) return;
      estimation::CircleObservation o;
      o.center_obj = arc.center;
      o.normal_obj = arc.normal;
      o.radius = arc.radius;
      o.xn = K.pixel_to_normalized(a.edge_px[static_cast<std::size_t>(k)]);
      o.sigma_px = p_.circle_sigma_px;
      o.camera = camera;
      out.circles.push_back(o);
      out.circle_refs.push_back(FeatureRef{view_index, static_cast<std::uint32_t>(i)});
    }
  }
}

}  // namespace v4r::pipeline
