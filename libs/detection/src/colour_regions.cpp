// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/colour_regions.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace v4r::detection {

namespace {

/// Normalised chromaticity (r, g) of an RGB triple; false when it is black.
bool chromaticity(const Eigen::Vector3f& rgb, float& r, float& g) {
  const float s = rgb.sum();
  if (!(s > 1e-6f)) return false;
  r = rgb.x() / s;
  g = rgb.y() / s;
  return true;
}

}  // namespace

ColourRegions::ColourRegions(const model::Model& model, const TemplateSet& ts, const geometry::PinholeCamera& cam,
                             const Eigen::Vector3f& rgb, const ColourParams& p)
    : p_(p), full_w_(cam.width), full_h_(cam.height), w_(std::max(1, cam.width / 4)), h_(std::max(1, cam.height / 4)) {
  chromaticity(rgb, r0_, g0_);
  // Footprints of the coarse templates: coloured faces facing the camera, projected with the
  // template's focal lengths at the coarse level's scale, relative to the anchor (the view has
  // the model's centre on the optical axis).
  constexpr float kSameColour = 0.02f;  // chromaticity difference of faces that count as the searched colour
  const double s = ts.coarse.scale;
  footprints_.resize(ts.coarse_views.size());
  float min_area = std::numeric_limits<float>::max();
  std::vector<Eigen::Vector2d> poly;
  for (std::size_t k = 0; k < ts.coarse_views.size(); ++k) {
    const geometry::SE3& T = ts.views[ts.coarse_views[k]].T_cam_obj;
    const Eigen::Matrix3d R = T.rotation();
    double area = 0.0, x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
    for (const model::Face& f : model.faces()) {
      float fr = 0.0f, fg = 0.0f;
      if (!f.attr.colour || !chromaticity(*f.attr.colour, fr, fg)) continue;
      if (std::abs(fr - r0_) > kSameColour || std::abs(fg - g0_) > kSameColour) continue;
      const Eigen::Vector3d p0 = T * model.junctions()[f.loop[0]].p;
      if ((R * f.normal).dot(p0) >= 0.0) continue;  // seen from behind
      poly.clear();
      bool in_front = true;
      for (const model::Index j : f.loop) {
        const Eigen::Vector3d q = T * model.junctions()[j].p;
        if (q.z() <= 1e-6) {
          in_front = false;
          break;
        }
        poly.emplace_back(s * ts.fx * q.x() / q.z(), s * ts.fy * q.y() / q.z());
      }
      if (!in_front) continue;
      double a2 = 0.0;
      for (std::size_t i = 0; i < poly.size(); ++i) {
        const Eigen::Vector2d& u = poly[i];
        const Eigen::Vector2d& v = poly[(i + 1) % poly.size()];
        a2 += u.x() * v.y() - u.y() * v.x();
        x0 = std::min(x0, u.x());
        x1 = std::max(x1, u.x());
        y0 = std::min(y0, u.y());
        y1 = std::max(y1, u.y());
      }
      area += 0.5 * std::abs(a2);
    }
    ColouredFootprint& fp = footprints_[k];
    if (area <= 0.0) continue;
    fp.area = static_cast<float>(area);
    fp.x0 = static_cast<std::int16_t>(std::floor(x0));
    fp.y0 = static_cast<std::int16_t>(std::floor(y0));
    fp.x1 = static_cast<std::int16_t>(std::ceil(x1));
    fp.y1 = static_cast<std::int16_t>(std::ceil(y1));
    min_area = std::min(min_area, fp.area);
    max_area_ = std::max(max_area_, fp.area);
  }
  if (max_area_ > 0.0f) {
    min_region_ = std::max(static_cast<float>(p_.min_region_px), static_cast<float>(p_.min_area_ratio) * min_area);
    max_region_ = static_cast<float>(p_.max_area_ratio) * max_area_;
  }
  const std::size_t n = static_cast<std::size_t>(w_) * h_;
  mask_.assign(n, 0);
  stack_.assign(n, 0);
  regions_.reserve(static_cast<std::size_t>(std::max(1, p_.max_regions)));
}

int ColourRegions::find(const image::ColourView& bgr) {
  regions_.clear();
  if (bgr.empty() || bgr.width != full_w_ || bgr.height != full_h_) return -1;
  // Back-projection: 4x4 block sums of B, G, R, their chromaticity against the model's.
  const float min_sum = static_cast<float>(3.0 * 16.0 * p_.min_brightness);
  const float d2max = static_cast<float>(p_.max_distance * p_.max_distance);
  for (int y = 0; y < h_; ++y) {
    std::uint8_t* m = mask_.data() + static_cast<std::size_t>(y) * w_;
    for (int x = 0; x < w_; ++x) {
      int sb = 0, sg = 0, sr = 0;
      for (int dy = 0; dy < 4; ++dy) {
        const std::uint8_t* px = bgr.pixel(4 * x, 4 * y + dy);
        for (int dx = 0; dx < 4; ++dx, px += 3) {
          sb += px[0];
          sg += px[1];
          sr += px[2];
        }
      }
      const float sum = static_cast<float>(sb + sg + sr);
      if (sum < min_sum || sum <= 0.0f) {
        m[x] = 0;
        continue;
      }
      const float dr = static_cast<float>(sr) / sum - r0_, dg = static_cast<float>(sg) / sum - g0_;
      m[x] = dr * dr + dg * dg <= d2max ? 255 : 0;
    }
  }
  // 8-connected regions by flood fill (255: marked, not yet visited; 1: visited).
  const std::size_t cap = regions_.capacity();
  for (int y0 = 0; y0 < h_; ++y0)
    for (int x0 = 0; x0 < w_; ++x0) {
      const std::size_t seed = static_cast<std::size_t>(y0) * w_ + x0;
      if (mask_[seed] != 255) continue;
      ColourRegion r{x0, y0, x0, y0, 0};
      std::size_t top = 0;
      stack_[top++] = static_cast<std::int32_t>(seed);
      mask_[seed] = 1;
      while (top > 0) {
        const std::int32_t i = stack_[--top];
        const int x = i % w_, y = i / w_;
        ++r.area;
        r.x0 = std::min(r.x0, x);
        r.x1 = std::max(r.x1, x);
        r.y0 = std::min(r.y0, y);
        r.y1 = std::max(r.y1, y);
        for (int yy = std::max(0, y - 1); yy <= std::min(h_ - 1, y + 1); ++yy)
          for (int xx = std::max(0, x - 1); xx <= std::min(w_ - 1, x + 1); ++xx) {
            const std::size_t j = static_cast<std::size_t>(yy) * w_ + xx;
            if (mask_[j] != 255) continue;
            mask_[j] = 1;
            stack_[top++] = static_cast<std::int32_t>(j);
          }
      }
      if (static_cast<float>(r.area) < min_region_ || static_cast<float>(r.area) > max_region_) continue;
      if (regions_.size() < cap) {
        regions_.push_back(r);
        continue;
      }
      auto smallest = std::min_element(regions_.begin(), regions_.end(),
                                       [](const ColourRegion& a, const ColourRegion& b) { return a.area < b.area; });
      if (smallest->area < r.area) *smallest = r;
    }
  for (std::uint8_t& m : mask_) m = m ? 255 : 0;
  std::sort(regions_.begin(), regions_.end(), [](const ColourRegion& a, const ColourRegion& b) { return a.area > b.area; });
  return static_cast<int>(regions_.size());
}

bool ColourRegions::anchor_window(std::size_t k, const ColourRegion& r, int& ax0, int& ay0, int& ax1, int& ay1) const {
  const ColouredFootprint& fp = footprints_[k];
  if (fp.area <= 0.0f) return false;
  const float ratio = static_cast<float>(r.area) / fp.area;
  if (ratio < p_.min_area_ratio || ratio > p_.max_area_ratio) return false;
  const int m = p_.margin;
  // Anchors a with a + fp.x0 <= r.x0 + m and a + fp.x1 >= r.x1 - m: the footprint holds the
  // region; a region wider than the footprint: the two centred, +- m.
  const auto axis = [m](int r0, int r1, int f0, int f1, int& lo, int& hi) {
    lo = r1 - m - f1;
    hi = r0 + m - f0;
    if (lo > hi) {
      const int c = (r0 + r1 - f0 - f1) / 2;
      lo = c - m;
      hi = c + m;
    }
  };
  axis(r.x0, r.x1, fp.x0, fp.x1, ax0, ax1);
  axis(r.y0, r.y1, fp.y0, fp.y1, ay0, ay1);
  return true;
}

}  // namespace v4r::detection
