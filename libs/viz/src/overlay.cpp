// v4r - robust model-based object tracking. MIT licence.
#include "v4r/viz/overlay.hpp"

#include <iterator>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace v4r::viz {

namespace {
cv::Point2f pt(const Eigen::Vector2d& p) { return {static_cast<float>(p.x()), static_cast<float>(p.y())}; }

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kScale = 0.45;

/// White text on a darkened band, readable on any background.
void label(cv::Mat& bgr, const std::string& text, cv::Point origin, cv::Scalar colour = cv::Scalar(255, 255, 255)) {
  int base = 0;
  const cv::Size size = cv::getTextSize(text, kFont, kScale, 1, &base);
  cv::Rect band(origin.x - 3, origin.y - size.height - 3, size.width + 6, size.height + base + 6);
  band &= cv::Rect(0, 0, bgr.cols, bgr.rows);
  if (band.area() > 0) {
    cv::Mat roi = bgr(band);
    roi.convertTo(roi, -1, 0.35, 0.0);
  }
  cv::putText(bgr, text, origin, kFont, kScale, colour, 1, cv::LINE_AA);
}

/// The object's axes at its origin, a third of its bounding radius long (x red, y green, z blue).
void draw_axes(cv::Mat& bgr, const geometry::PinholeCamera& K, const geometry::SE3& T, double length) {
  const Eigen::Vector3d o = T * Eigen::Vector3d::Zero();
  if (o.z() <= 1e-6) return;
  const Eigen::Vector2d po = K.project(o);
  const Eigen::Vector3d axes[3] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()};
  const cv::Scalar colours[3] = {cv::Scalar(0, 0, 255), cv::Scalar(0, 200, 0), cv::Scalar(255, 80, 0)};
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d e = T * (axes[k] * length);
    if (e.z() <= 1e-6) continue;
    cv::arrowedLine(bgr, pt(po), pt(K.project(e)), colours[k], 2, cv::LINE_AA, 0, 0.15);
  }
}

void draw_legend(cv::Mat& bgr) {
  struct Key {
    const char* text;
    cv::Scalar colour;
  };
  const Key keys[] = {{"found", cv::Scalar(0, 255, 0)},     {"outlier", cv::Scalar(0, 255, 255)},
                      {"missed", cv::Scalar(0, 0, 255)},     {"ambiguous", cv::Scalar(160, 160, 160)},
                      {"edge pixels", cv::Scalar(255, 255, 0)}};
  int y = bgr.rows - 10 - 16 * (static_cast<int>(std::size(keys)) - 1);
  for (const Key& k : keys) {
    int base = 0;
    const cv::Size size = cv::getTextSize(k.text, kFont, kScale, 1, &base);
    label(bgr, k.text, cv::Point(bgr.cols - size.width - 8, y), k.colour);
    y += 16;
  }
}
}  // namespace

void draw_overlay(cv::Mat& bgr, const scene::Scene& scene, const pipeline::VisionCycle& cycle, std::size_t camera,
                  const pipeline::CycleReport& report, const OverlayStyle& style) {
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
    if (style.axes && obj.model && obj.status != scene::TrackStatus::kUninitialised)
      draw_axes(bgr, K, scene.cameras()[camera].T_ref_cam.inverse() * obj.T_ref_obj, obj.model->bounding_radius() / 3.0);
  }
  for (const Eigen::Vector2d& p : cycle.edgels(camera)) {
    cv::circle(bgr, pt(p), 1, cv::Scalar(255, 255, 0), cv::FILLED, cv::LINE_8);
  }
  // Text last, above everything drawn.
  for (std::size_t oi = 0; oi < scene.objects().size() && oi < report.objects.size(); ++oi) {
    const pipeline::ObjectReport& r = report.objects[oi];
    const std::string& name = style.object_label.empty() ? scene.objects()[oi].name : style.object_label;
    label(bgr, fmt::format("{}: {}  quality {:.2f}  rms {:.2f} px", name, scene::to_string(r.status), r.quality, r.rms_px),
          cv::Point(8, 18 + 18 * row++));
    label(bgr,
          fmt::format("  edges+circles found {}/{}; solve used {} lines, {} circle pts, {} junctions",
                      r.features_found, r.features_visible, r.lines_used, r.circle_points_used, r.junctions_used),
          cv::Point(8, 18 + 18 * row++));
  }
  label(bgr, fmt::format("frame {}  cycle {:.2f} ms", report.frame, report.cycle_ms), cv::Point(8, bgr.rows - 10));
  if (style.legend) draw_legend(bgr);
}

}  // namespace v4r::viz
