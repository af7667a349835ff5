// v4r - robust model-based object tracking. MIT licence.
#include "v4r/features/edge_evidence.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace v4r::features {

bool EdgeEvidence::add_sample(const image::ImageView& img, const Eigen::Vector2d& p, const Eigen::Vector2d& n,
                              float threshold) {
  if (img.empty() || !p.allFinite() || !n.allFinite()) return false;
  const int search = std::clamp(p_.search_px, 0, kMaxSearch);
  const int reach = search + 2;
  const Eigen::Vector2d e(-n.y(), n.x());
  const Eigen::Vector2d ext = reach * n.cwiseAbs() + kAlong * e.cwiseAbs();
  if (!img.contains(p.x() - ext.x(), p.y() - ext.y(), 0.5) || !img.contains(p.x() + ext.x(), p.y() + ext.y(), 0.5))
    return false;
  ++samples_;
  // Profile across the edge, smoothed along it (noise), and the difference along it at each
  // offset (orientation): v(o) = mean_t I(p + o n + t e), g_n(o) = (v(o+1) - v(o-1)) / 2,
  // g_e(o) = (I(p + o n + kAlong e) - I(p + o n - kAlong e)) / (2 kAlong). Every sample lies
  // inside the image by half a pixel (checked above), so bilinear sampling needs no clamping.
  // Offsets are computed lazily, from the predicted position outwards: most samples of a
  // tracked model match at or next to it, and the search stops at the first match.
  const float px = static_cast<float>(p.x()), py = static_cast<float>(p.y());
  const float nx = static_cast<float>(n.x()), ny = static_cast<float>(n.y());
  const float ex = -ny, ey = nx;
  const std::uint8_t* data = img.data;
  const long stride = img.stride;
  const auto bilinear = [data, stride](float x, float y) {
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const float ax = x - static_cast<float>(x0), ay = y - static_cast<float>(y0);
    const std::uint8_t* r0 = data + static_cast<long>(y0) * stride + x0;
    const std::uint8_t* r1 = r0 + stride;
    const float top = r0[0] + ax * (static_cast<float>(r0[1]) - r0[0]);
    const float bot = r1[0] + ax * (static_cast<float>(r1[1]) - r1[0]);
    return top + ay * (bot - top);
  };
  constexpr int kSize = 2 * (kMaxSearch + 2) + 1;
  std::array<float, kSize> v{}, ge{};
  std::array<bool, kSize> have{};
  const auto column = [&](int o) {
    const auto i = static_cast<std::size_t>(o + reach);
    if (have[i]) return;
    have[i] = true;
    const float qx = px + static_cast<float>(o) * nx, qy = py + static_cast<float>(o) * ny;
    float acc = 0.0f, first = 0.0f, last = 0.0f;
    for (int t = -kAlong; t <= kAlong; ++t) {
      const float val = bilinear(qx + static_cast<float>(t) * ex, qy + static_cast<float>(t) * ey);
      acc += val;
      if (t == -kAlong) first = val;
      if (t == kAlong) last = val;
    }
    v[i] = acc / (2 * kAlong + 1);
    ge[i] = (last - first) / (2 * kAlong);
  };
  const auto grad_n = [&](int o) {
    const auto i = static_cast<std::size_t>(o + reach);
    return 0.5f * (v[i + 1] - v[i - 1]);
  };
  const float thr = std::max(threshold, p_.min_gradient);
  const float cos_max = static_cast<float>(std::cos(p_.max_angle_rad));
  // A match is a local maximum of the gradient across (the edge's position, not the flank of a
  // blurred edge a few pixels away) within search_px, strong enough and oriented along the edge.
  for (int k = 0; k <= 2 * search; ++k) {
    const int o = (k % 2 == 1) ? -(k + 1) / 2 : k / 2;  // 0, -1, 1, -2, 2, ...
    for (int q = o - 2; q <= o + 2; ++q) column(q);
    const float gm = grad_n(o);
    const float g = std::abs(gm);
    if (g < thr || g < std::abs(grad_n(o - 1)) || g < std::abs(grad_n(o + 1))) continue;
    const float gt = ge[static_cast<std::size_t>(o + reach)];
    if (g >= cos_max * std::sqrt(gm * gm + gt * gt)) {
      ++matched_;
      return true;
    }
  }
  return false;
}

int EdgeEvidence::samples_for_length(double length_px) const {
  if (!(length_px > 0.0)) return 1;
  const double step = std::max(1.0, p_.step_px);
  return std::clamp(static_cast<int>(length_px / step), 1, std::max(1, p_.max_samples_per_edge));
}

int EdgeEvidence::add_segment(const image::ImageView& img, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                              float threshold) {
  const Eigen::Vector2d d = b - a;
  const double len = d.norm();
  if (!(len > 1e-9)) return 0;
  const Eigen::Vector2d n(-d.y() / len, d.x() / len);
  const int k = samples_for_length(len);
  int hits = 0;
  for (int i = 0; i < k; ++i) {
    const double s = (i + 0.5) / k;
    hits += add_sample(img, a + s * d, n, threshold) ? 1 : 0;
  }
  return hits;
}

}  // namespace v4r::features
