// v4r - robust model-based object tracking. MIT licence.
#include "v4r/viz/overlay.hpp"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace v4r::viz {

namespace {
cv::Point2f pt(const Eigen::Vector2d& p) { return {static_cast<float>(p.x()), static_cast<float>(p.y())}; }
}  // namespace

void draw_overlay(cv::Mat& bgr, const scene::Scene& scene, const pipeline::VisionCycle& cycle, std::size_t camera,
                  const pipeline::CycleReport& report) {
  if (bgr.empty() || camera >= scene.cameras().size()) return;
  const geometry::PinholeCamera& K = scene.cameras()[camera].intrinsics;
  int row = 0;
  for (std::size_t oi = 0; oi < scene.objects().size(); ++oi) {
    const scene::Object& obj = scene.objects()[oi];
    for (const scene::View& view : obj.views) {
      if (view.camera != camera) continue;
      const geometry::SE3 T = scene.cameras()[camera].T_ref_cam.inverse() * obj.T_ref_obj;
      for (const scene::LineFeature& f : view.lines) {
        if (!f.visible) continue;
        cv::Scalar colour(0, 0, 255);
        if (f.status == scene::FeatureStatus::kFound) colour = cv::Scalar(0, 255, 0);
        if (f.status == scene::FeatureStatus::kOutlier) colour = cv::Scalar(0, 255, 255);
        if (f.ambiguous) colour = cv::Scalar(160, 160, 160);
        // The model edge projected with the final pose, piecewise so that distortion shows.
        constexpr int kPieces = 8;
        Eigen::Vector2d prev = K.project(T * f.X1);
        for (int k = 1; k <= kPieces; ++k) {
          const Eigen::Vector3d X = f.X1 + (f.X2 - f.X1) * (static_cast<double>(k) / kPieces);
          const Eigen::Vector2d cur = K.project(T * X);
          cv::line(bgr, pt(prev), pt(cur), colour, 1, cv::LINE_AA);
          prev = cur;
        }
      }
      for (const scene::ArcFeature& a : view.arcs) {
        if (!a.visible || a.samples < 2) continue;
        const cv::Scalar colour = a.status == scene::FeatureStatus::kFound ? cv::Scalar(0, 255, 0) : cv::Scalar(0, 0, 255);
        // Visible samples are a subset of evenly spaced ones: join neighbours only, not across gaps.
        double step = 1e9;
        for (int k = 0; k + 1 < a.samples; ++k) step = std::min(step, (a.X[k + 1] - a.X[k]).norm());
        for (int k = 0; k + 1 < a.samples; ++k)
          if ((a.X[k + 1] - a.X[k]).norm() < 1.5 * step)
            cv::line(bgr, pt(K.project(T * a.X[k])), pt(K.project(T * a.X[k + 1])), colour, 1, cv::LINE_AA);
      }
    }
    if (oi < report.objects.size()) {
      const pipeline::ObjectReport& r = report.objects[oi];
      const std::string text = fmt::format("{} {} found {}/{} used {} rms {:.2f}px q {:.2f}", obj.name,
                                           scene::to_string(r.status), r.features_found, r.features_visible,
                                           r.features_used, r.rms_px, r.quality);
      cv::putText(bgr, text, cv::Point(8, 18 + 18 * row++), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255, 255, 255), 1,
                  cv::LINE_AA);
    }
  }
  for (const Eigen::Vector2d& p : cycle.edgels(camera)) {
    cv::circle(bgr, pt(p), 1, cv::Scalar(255, 255, 0), cv::FILLED, cv::LINE_8);
  }
  cv::putText(bgr, fmt::format("frame {} cycle {:.2f} ms", report.frame, report.cycle_ms),
              cv::Point(8, bgr.rows - 10), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
}

}  // namespace v4r::viz
