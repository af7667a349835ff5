// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/line_measurement.hpp"

#include <algorithm>
#include <cmath>

namespace v4r::pipeline {

namespace {

features::LineTrackerParams line_params(const CycleParams& p, int half_width, int rows) {
  features::LineTrackerParams s = p.track;
  s.half_width = half_width;
  s.rows = rows;
  return s;
}

/// The measured line in normalised undistorted coordinates. Under lens distortion a straight edge
/// is curved in the image, so the edge pixels are undistorted one by one and a line is fitted to
/// them (total least squares); its ends are the undistorted window ends projected onto it.
void undistorted_line(const geometry::PinholeCamera& K, const features::LineMeasurement& m,
                      const std::vector<Eigen::Vector2d>& edgels, std::vector<Eigen::Vector2d>& buffer,
                      Eigen::Vector2d& n1, Eigen::Vector2d& n2) {
  n1 = K.pixel_to_normalized(m.line.a);
  n2 = K.pixel_to_normalized(m.line.b);
  if (!K.has_distortion() || edgels.size() < 3 || edgels.size() > buffer.capacity()) return;
  buffer.clear();
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& e : edgels) {
    buffer.push_back(K.pixel_to_normalized(e));
    c += buffer.back();
  }
  c /= static_cast<double>(buffer.size());
  Eigen::Matrix2d S = Eigen::Matrix2d::Zero();
  for (const Eigen::Vector2d& q : buffer) S += (q - c) * (q - c).transpose();
  // Principal direction of the 2x2 scatter matrix.
  const double theta = 0.5 * std::atan2(2.0 * S(0, 1), S(0, 0) - S(1, 1));
  Eigen::Vector2d dir(std::cos(theta), std::sin(theta));
  if (dir.dot(n2 - n1) < 0) dir = -dir;
  n1 = c + dir * dir.dot(n1 - c);
  n2 = c + dir * dir.dot(n2 - c);
}

}  // namespace

LineMeasurement::LineMeasurement(const CycleParams& p)
    : p_(p),
      tracker_(p.track),
      reduced_tracker_(line_params(p, p.track.half_width, std::max(3, p.budget.reduced_rows))) {
  const int levels = std::max(0, p.recovery.max_search_level) + 1;
  searchers_.reserve(static_cast<std::size_t>(levels));
  for (int L = 0; L < levels; ++L) {
    // Level 0 searches new and lost features; higher levels search wider and coarser after bad frames.
    const int rows = L == 0 ? p.track.rows : std::max(8, p.track.rows / 2);
    searchers_.emplace_back(line_params(p, p.search_half_width * (1 + L), rows));
  }
}

void LineMeasurement::reserve(std::size_t rows) {
  if (undistorted_.capacity() < rows * 4) undistorted_.reserve(rows * 4);
}

int LineMeasurement::track(scene::View& view, const scene::Camera& cam, const CameraImage& img, MeasureContext& ctx) {
  const CycleParams& p = p_;
  const geometry::PinholeCamera& K = cam.intrinsics;
  const image::ColourView* colour = img.colour.empty() ? nullptr : &img.colour;
  int found = 0;
  for (std::size_t fi = 0; fi < view.lines.size(); ++fi) {
    scene::LineFeature& f = view.lines[fi];
    if (!f.visible || f.ambiguous || f.dropped) continue;
    // Back-off (see CycleParams::search_backoff_frames): long-missed features wait their turn,
    // spread over the frames by their index.
    if (ctx.backing_off(f.frames_missing, fi, p.search_backoff_frames, p.search_backoff_period)) {
      f.measurement = features::LineMeasurement{};
      f.retrack = false;
      continue;
    }
    // The first pass measures every feature: features not found in the last frame are searched
    // in the wide window (wider still after bad frames), found ones tracked in the narrow one.
    // Later passes start from the fresh pose and measure again, in the narrow window, only what
    // was missed or rejected: a found edge's line does not depend on where its window sat.
    if (ctx.first_pass || f.retrack) {
      f.predicted.a = K.project(view.T_cam_obj * f.X1);
      f.predicted.b = K.project(view.T_cam_obj * f.X2);
      const bool search = ctx.first_pass && (f.status != scene::FeatureStatus::kFound || ctx.search_level > 0);
      features::LineTracker& t = search ? searchers_[std::min<std::size_t>(static_cast<std::size_t>(ctx.search_level),
                                                                           searchers_.size() - 1)]
                                        : (ctx.degrade_level >= 1 ? reduced_tracker_ : tracker_);
      f.measurement = t.track(img.grey, f.predicted, f.track, colour, f.range);
      if (!ctx.first_pass && f.measurement.found) ++ctx.refound;
      ctx.samples += t.params().rows;
      ++ctx.windows;
      // Re-measured in a later pass: missed in the narrow window (the fresh pose may bring the
      // edge into it); a miss in the wide search window already covered the narrow one.
      f.retrack = !f.measurement.found && !search;
      if (f.measurement.found) {
        undistorted_line(K, f.measurement, t.last_inliers(), undistorted_, f.line_n1, f.line_n2);
        if (ctx.edgels != nullptr)
          for (const Eigen::Vector2d& e : t.last_inliers())
            if (ctx.edgels->size() < ctx.edgels->capacity()) ctx.edgels->push_back(e);
      }
    }
    if (f.measurement.found) ++found;
  }
  return found;
}

void LineMeasurement::observations(const scene::View& view, std::uint16_t view_index, std::uint8_t camera,
                                   ObservationBuffer& out) const {
  for (std::size_t i = 0; i < view.lines.size(); ++i) {
    const scene::LineFeature& f = view.lines[i];
    if (!f.visible || f.ambiguous || f.dropped || !f.measurement.found) continue;
    if (out.lines.size() >= out.lines.capacity()) return;  // (reserved: one per edge and view)
    estimation::LineObservation o;
    o.X1_obj = f.X1;
    o.X2_obj = f.X2;
    o.xn1 = f.line_n1;
    o.xn2 = f.line_n2;
    o.sigma_px = f.sigma_px > 0.0 ? f.sigma_px : p_.line_sigma_px;
    o.camera = camera;
    out.lines.push_back(o);
    out.line_refs.push_back(FeatureRef{view_index, static_cast<std::uint32_t>(i)});
  }
}

}  // namespace v4r::pipeline
