// v4r - robust model-based object tracking. MIT licence.
#include "v4r/features/edge_evidence.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace v4r::features {

bool EdgeEvidence::add_sample(const image::ImageView& img, const Eigen::Vector2d& p, const Eigen::Vector2d& n,
                              float threshold) {
  if (img.empty() || !p.allFinite() || !n.allFinite()) return false;
  constexpr int kAlong = 2;  // the profile is averaged over 2 * kAlong + 1 pixels along the edge
  const int reach = std::clamp(p_.search_px, 0, kMaxSearch) + 2;
  const Eigen::Vector2d e(-n.y(), n.x());
  const Eigen::Vector2d ext = reach * n.cwiseAbs() + kAlong * e.cwiseAbs();
  if (!img.contains(p.x() - ext.x(), p.y() - ext.y(), 0.5) || !img.contains(p.x() + ext.x(), p.y() + ext.y(), 0.5))
    return false;
  ++samples_;
  // Profile across the edge, smoothed along it (noise), and the difference along it at each
  // offset (orientation): v(o) = mean_t I(p + o n + t e), g_n(o) = (v(o+1) - v(o-1)) / 2,
  // g_e(o) = (I(p + o n + kAlong e) - I(p + o n - kAlong e)) / (2 kAlong).
  std::array<float, 2 * kMaxSearch + 5> v{}, ge{};
  const int span = reach;
  // The profile is filled as far as the test below needs it: it stops at the first match. Its
  // bilinear samples skip ImageView::sample's clamp: the box checked above holds them.
  int filled = -span;
  const auto fill_to = [&](int last_o) {
    for (; filled <= last_o; ++filled) {
      const Eigen::Vector2d q = p + static_cast<double>(filled) * n;
      const float first = img.sample_inside(q.x() - kAlong * e.x(), q.y() - kAlong * e.y());
      const float last = img.sample_inside(q.x() + kAlong * e.x(), q.y() + kAlong * e.y());
      float acc = first;
      for (int t = -kAlong + 1; t < kAlong; ++t) acc += img.sample_inside(q.x() + t * e.x(), q.y() + t * e.y());
      acc += last;
      v[static_cast<std::size_t>(filled + span)] = acc / (2 * kAlong + 1);
      ge[static_cast<std::size_t>(filled + span)] = (last - first) / (2 * kAlong);
    }
  };
  const auto gn = [&v](std::size_t i) { return 0.5f * (v[i + 1] - v[i - 1]); };
  const float thr = std::max(threshold, p_.min_gradient);
  const float cos_max = static_cast<float>(std::cos(p_.max_angle_rad));
  // A match is a local maximum of the gradient across (the edge's position, not the flank of a
  // blurred edge a few pixels away) within search_px, strong enough and oriented along the edge.
  for (int o = -span + 2; o <= span - 2; ++o) {
    fill_to(o + 2);
    const auto i = static_cast<std::size_t>(o + span);
    const float gi = gn(i), g = std::abs(gi);
    if (g < thr || g < std::abs(gn(i - 1)) || g < std::abs(gn(i + 1))) continue;
    if (g >= cos_max * std::sqrt(gi * gi + ge[i] * ge[i])) {
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
