// v4r - robust model-based object tracking. MIT licence.
#include "v4r/features/edge_evidence.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace v4r::features {

namespace {

/// The five bilinear samples I(q + t e), t = -2 .. 2 (inside the image: checked by the caller).
/// The first four at once where GCC's vector extension is available (SSE2 or NEON; positions in
/// double precision, the blend in single, as ImageView::sample_inside: the same values).
void across_samples(const image::ImageView& img, const Eigen::Vector2d& q, const Eigen::Vector2d& e, float s[5]) {
#if defined(__GNUC__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  if (static_cast<long long>(img.stride) * img.height < (1LL << 31)) {  // byte offsets fit an int
    using D4 = double __attribute__((vector_size(32)));
    using F4 = float __attribute__((vector_size(16)));
    using I4 = int __attribute__((vector_size(16)));
    const D4 t = {-2.0, -1.0, 0.0, 1.0};
    const D4 x = q.x() + t * e.x(), y = q.y() + t * e.y();
    const I4 x0 = __builtin_convertvector(x, I4), y0 = __builtin_convertvector(y, I4);
    const F4 ax = __builtin_convertvector(x - __builtin_convertvector(x0, D4), F4);
    const F4 ay = __builtin_convertvector(y - __builtin_convertvector(y0, D4), F4);
    // Byte offsets y0 * stride + x0, exact in double.
    const I4 offset = __builtin_convertvector(
        __builtin_convertvector(y0, D4) * static_cast<double>(img.stride) + __builtin_convertvector(x0, D4), I4);
    // A pixel and its right neighbour in one 16-bit load (little-endian: the pixel in the low byte).
    const auto pair = [](const std::uint8_t* px) {
      std::uint16_t w;
      std::memcpy(&w, px, sizeof w);
      return static_cast<int>(w);
    };
    I4 top_pair, bottom_pair;
    for (int k = 0; k < 4; ++k) {
      const std::uint8_t* r0 = img.data + offset[k];
      top_pair[k] = pair(r0);
      bottom_pair[k] = pair(r0 + img.stride);
    }
    const F4 p00 = __builtin_convertvector(top_pair & 0xff, F4), p01 = __builtin_convertvector(top_pair >> 8, F4);
    const F4 p10 = __builtin_convertvector(bottom_pair & 0xff, F4), p11 = __builtin_convertvector(bottom_pair >> 8, F4);
    const F4 top = p00 + ax * (p01 - p00);
    const F4 bot = p10 + ax * (p11 - p10);
    const F4 val = top + ay * (bot - top);
    for (int k = 0; k < 4; ++k) s[k] = val[k];
    s[4] = img.sample_inside(q.x() + 2 * e.x(), q.y() + 2 * e.y());
    return;
  }
#endif
  for (int t = -2; t <= 2; ++t) s[t + 2] = img.sample_inside(q.x() + t * e.x(), q.y() + t * e.y());
}

}  // namespace

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
      float s[2 * kAlong + 1];  // the samples at t = -kAlong .. kAlong along the edge
      across_samples(img, q, e, s);
      const float first = s[0], last = s[2 * kAlong];
      float acc = first;
      for (int t = 1; t < 2 * kAlong; ++t) acc += s[t];
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
