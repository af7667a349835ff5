// v4r - robust model-based object tracking. MIT licence.
#include "v4r/features/silhouette_contrast.hpp"

#include <algorithm>
#include <cmath>

namespace v4r::features {

void SilhouetteContrast::reset() {
  for (int i = 0; i < inside_n_; ++i) hist_[static_cast<std::size_t>(inside_[static_cast<std::size_t>(i)])] = 0;
  inside_n_ = outside_n_ = leaked_ = 0;
}

int SilhouetteContrast::bin_of(const float bgr[3]) {
  const float s = bgr[0] + bgr[1] + bgr[2] + 1.0f;
  const int g = std::clamp(static_cast<int>(bgr[1] / s / 0.03f), 0, kChromaBins - 1);
  const int r = std::clamp(static_cast<int>(bgr[2] / s / 0.03f), 0, kChromaBins - 1);
  const int l = std::clamp(static_cast<int>(std::log(s) / 0.25f), 0, kLogBins - 1);
  return (l * kChromaBins + r) * kChromaBins + g;
}

bool SilhouetteContrast::sample(const image::ImageView& grey, const image::ColourView& colour,
                                const Eigen::Vector2d& p, int* bin) const {
  if (!p.allFinite()) return false;
  float bgr[3];
  if (!colour.empty()) {
    if (!colour.contains(p.x(), p.y(), 1.0)) return false;
    colour.sample_inside(p.x(), p.y(), bgr);
  } else {
    if (grey.empty() || !grey.contains(p.x(), p.y(), 1.0)) return false;
    bgr[0] = bgr[1] = bgr[2] = grey.sample(p.x(), p.y());
  }
  *bin = bin_of(bgr);
  return true;
}

void SilhouetteContrast::add_point(const image::ImageView& grey, const image::ColourView& colour,
                                   const Eigen::Vector2d& p, const Eigen::Vector2d& outward, double inside_extent_px,
                                   std::uint32_t group) {
  if (!p.allFinite() || !outward.allFinite()) return;
  const double deepest = std::max(1.0, inside_extent_px);
  for (const double d : p_.offsets_px) {
    if (inside_n_ >= kMaxSamples || outside_n_ >= kMaxSamples) return;
    int in = 0, out = 0;
    if (!sample(grey, colour, p - std::min(d, deepest) * outward, &in) || !sample(grey, colour, p + d * outward, &out)) continue;
    std::uint16_t& h = hist_[static_cast<std::size_t>(in)];
    if (h < 0xffff) ++h;
    group_[static_cast<std::size_t>(inside_n_)] = group;
    inside_[static_cast<std::size_t>(inside_n_++)] = in;
    outside_[static_cast<std::size_t>(outside_n_++)] = out;
  }
}

bool SilhouetteContrast::looks_inside(const Histogram& h, int bin, int need) {
  const int g = bin % kChromaBins, r = (bin / kChromaBins) % kChromaBins, l = bin / (kChromaBins * kChromaBins);
  int count = 0;
  for (int dl = -1; dl <= 1 && count < need; ++dl)
    for (int dr = -1; dr <= 1 && count < need; ++dr)
      for (int dg = -1; dg <= 1 && count < need; ++dg) {
        const int L = l + dl, R = r + dr, G = g + dg;
        if (L < 0 || L >= kLogBins || R < 0 || R >= kChromaBins || G < 0 || G >= kChromaBins) continue;
        count += h[static_cast<std::size_t>((L * kChromaBins + R) * kChromaBins + G)];
      }
  return count >= need;
}

void SilhouetteContrast::finish() {
  leaked_ = 0;
  if (inside_n_ == 0) return;
  const auto need_of = [&](int n) { return std::max(1, static_cast<int>(std::ceil(p_.match_share * n))); };
  const int need_all = need_of(inside_n_);
  // (Inside and outside samples are taken in pairs: index i is one pair, of group group_[i].)
  for (int s = 0; s < outside_n_;) {
    int e = s + 1;
    while (e < outside_n_ && group_[static_cast<std::size_t>(e)] == group_[static_cast<std::size_t>(s)]) ++e;
    const bool own = p_.min_group_samples > 0 && e - s >= p_.min_group_samples && e - s < inside_n_;
    if (own)
      for (int i = s; i < e; ++i) {
        std::uint16_t& h = group_hist_[static_cast<std::size_t>(inside_[static_cast<std::size_t>(i)])];
        if (h < 0xffff) ++h;
      }
    const Histogram& h = own ? group_hist_ : hist_;
    const int need = own ? need_of(e - s) : need_all;
    for (int i = s; i < e; ++i)
      if (looks_inside(h, outside_[static_cast<std::size_t>(i)], need)) ++leaked_;
    if (own)
      for (int i = s; i < e; ++i) group_hist_[static_cast<std::size_t>(inside_[static_cast<std::size_t>(i)])] = 0;
    s = e;
  }
}

}  // namespace v4r::features
