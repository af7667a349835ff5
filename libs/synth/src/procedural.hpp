// v4r - robust model-based object tracking. MIT licence.
// Internal to the synth module: hashing, value noise and the periodic texture table.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace v4r::synth::detail {

inline constexpr int kTextureSize = 512;  ///< texels per side of the periodic texture table

/// \brief SplitMix64 finaliser: a well-mixed 64-bit hash of x.
inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

/// Uniform in [0, 1) from two keys.
inline double unit_hash(std::uint64_t a, std::uint64_t b) {
  return static_cast<double>(splitmix64(splitmix64(a) ^ (b * 0xD1B54A32D192ED03ull)) >> 11) * 0x1.0p-53;
}

inline float smoothstep(float e0, float e1, float x) {
  const float t = std::clamp((x - e0) / (e1 - e0), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

/// \brief Smooth 2-D value noise in [0, 1]: random values on an nx x ny lattice (periodic),
/// interpolated with a cubic fade. Coordinates are in lattice cells.
class ValueNoise2D {
 public:
  ValueNoise2D(std::uint64_t key, int nx, int ny) : nx_(nx), ny_(ny), v_(static_cast<std::size_t>(nx) * ny) {
    for (std::size_t i = 0; i < v_.size(); ++i) v_[i] = unit_hash(key, i);
  }
  [[nodiscard]] double operator()(double u, double v) const {
    const double fu = std::floor(u), fv = std::floor(v);
    double tu = u - fu, tv = v - fv;
    tu = tu * tu * (3.0 - 2.0 * tu);
    tv = tv * tv * (3.0 - 2.0 * tv);
    const int x0 = wrap(static_cast<long long>(fu), nx_), x1 = wrap(static_cast<long long>(fu) + 1, nx_);
    const int y0 = wrap(static_cast<long long>(fv), ny_), y1 = wrap(static_cast<long long>(fv) + 1, ny_);
    const double a = at(x0, y0) + tu * (at(x1, y0) - at(x0, y0));
    const double b = at(x0, y1) + tu * (at(x1, y1) - at(x0, y1));
    return a + tv * (b - a);
  }

 private:
  static int wrap(long long i, int n) {
    if (i >= 0 && i < n) return static_cast<int>(i);
    return static_cast<int>(((i % n) + n) % n);
  }
  [[nodiscard]] double at(int x, int y) const { return v_[static_cast<std::size_t>(y) * nx_ + x]; }
  int nx_, ny_;
  std::vector<double> v_;
};

/// Bilinear lookup in the periodic texture table (kTextureSize^2 floats) at texel coordinates (u, v).
inline float texture_at(const float* tex, double u, double v) {
  const double fu = std::floor(u), fv = std::floor(v);
  const float au = static_cast<float>(u - fu), av = static_cast<float>(v - fv);
  constexpr long long m = kTextureSize - 1;
  const auto iu = static_cast<long long>(fu), iv = static_cast<long long>(fv);
  const float* r0 = tex + (iv & m) * kTextureSize;
  const float* r1 = tex + ((iv + 1) & m) * kTextureSize;
  const long long u0 = iu & m, u1 = (iu + 1) & m;
  const float a = r0[u0] + au * (r0[u1] - r0[u0]);
  const float b = r1[u0] + au * (r1[u1] - r1[u0]);
  return a + av * (b - a);
}

}  // namespace v4r::synth::detail
