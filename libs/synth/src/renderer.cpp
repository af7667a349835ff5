// v4r - robust model-based object tracking. MIT licence.
//
// Ray-casting renderer.
// Per camera (constructor): the undistorted normalised coordinates of every pixel centre (a ray
// table: undistortion is iterative and too slow per frame), the sub-pixel sample pattern, the
// static background (with its random clutter) and a periodic fBm texture table.
// Per frame: (1) the model's surfaces (faces, cylinder sides and end disks) are moved to the
// camera frame and bounded in pixels (surfaces.cpp); (2) a z-buffer pass finds the nearest
// surface at every pixel centre; (3) a shading pass shades flat pixels with one sample and
// supersamples the pixels whose 4-neighbours see another surface; (4) the shadow band and the
// occluder are applied, sensor noise is added and the result quantised. With motion blur,
// steps 1-3 run once per sub-frame pose over the region the object sweeps, and are averaged.
// The surface texture is looked up at the hit point in 2-D coordinates of the surface (plane
// coordinates, or angle and height on a cylinder) in the OBJECT frame, so it moves with the object.
#include "v4r/synth/renderer.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

#include "effects.hpp"
#include "procedural.hpp"
#include "surfaces.hpp"

namespace v4r::synth {
namespace {

using detail::FrameLighting;
using detail::kTextureSize;
using detail::OccluderState;
using detail::ShadowState;
using detail::splitmix64;
using detail::Surface;
using detail::SurfaceKind;
using detail::unit_hash;

constexpr double kTexelsPerScale = 16.0;   ///< texels per RenderOptions::texture_scale
constexpr double kRayBoundsMargin = 0.05;  ///< relative margin around the ray table's extent
constexpr int kUndistortMaxIter = 200;     ///< fixed-point iterations per pixel (at most)
constexpr double kUndistortTol = 1e-14;    ///< normalised units: convergence of the undistortion

/// Rust albedo (BGR) blended into the steel where the texture's fBm exceeds kRustFrom (fully
/// at kRustTo), at most kRustMax * texture_strength; kMottle * texture_strength is the relative
/// brightness variation of the steel.
const Eigen::Vector3f kRust(0.10f, 0.24f, 0.46f);
constexpr float kRustFrom = 0.45f, kRustTo = 0.80f, kRustMax = 1.0f, kMottle = 1.0f;
/// Glints (specular micro-facets): where a finer copy of the texture exceeds kGlintFrom (fully at kGlintTo).
constexpr float kGlintFrom = 0.70f, kGlintTo = 0.78f;
constexpr double kGlintScale = 4.1;  ///< glint texture frequency relative to the rust texture

/// Normalised undistorted coordinates of a pixel: the fixed-point iteration of
/// PinholeCamera::pixel_to_normalized, warm-started (from a neighbouring pixel's solution) and
/// run to convergence, so that building a whole ray table is fast.
Eigen::Vector2d undistort(const geometry::PinholeCamera& cam, const Eigen::Vector2d& px, Eigen::Vector2d x) {
  const double xd = (px.x() - cam.cx) / cam.fx, yd = (px.y() - cam.cy) / cam.fy;
  if (!cam.has_distortion()) return {xd, yd};
  const auto& k = cam.dist;
  for (int i = 0; i < kUndistortMaxIter; ++i) {
    const double r2 = x.squaredNorm();
    const double radial = 1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]));
    const double dx = 2.0 * k[2] * x.x() * x.y() + k[3] * (r2 + 2.0 * x.x() * x.x());
    const double dy = k[2] * (r2 + 2.0 * x.y() * x.y()) + 2.0 * k[3] * x.x() * x.y();
    const Eigen::Vector2d next((xd - dx) / radial, (yd - dy) / radial);
    const double change = (next - x).cwiseAbs().maxCoeff();
    x = next;
    if (change < kUndistortTol) break;
  }
  return x;
}

/// \brief Nearest surface id (-1: background) and its depth (metres) at every pixel centre.
struct ZBuffer {
  int w = 0;
  std::vector<int> ids;
  std::vector<float> z;
  ZBuffer(int width, int height)
      : w(width),
        ids(static_cast<std::size_t>(width) * height, -1),
        z(ids.size(), std::numeric_limits<float>::infinity()) {}
  void clear(const cv::Rect& r) {
    for (int y = r.y; y < r.y + r.height; ++y) {
      const std::size_t o = static_cast<std::size_t>(y) * w;
      std::fill(ids.begin() + static_cast<long>(o + r.x), ids.begin() + static_cast<long>(o + r.x + r.width), -1);
      std::fill(z.begin() + static_cast<long>(o + r.x), z.begin() + static_cast<long>(o + r.x + r.width),
                std::numeric_limits<float>::infinity());
    }
  }
};

template <typename Hit>
void raster(const Surface& f, int k, const cv::Rect& region, const cv::Mat& rays, ZBuffer& zb, Hit hit) {
  const int xa = std::max(f.x0, region.x), xb = std::min(f.x1, region.x + region.width - 1);
  const int ya = std::max(f.y0, region.y), yb = std::min(f.y1, region.y + region.height - 1);
  for (int y = ya; y <= yb; ++y) {
    const auto* rrow = rays.ptr<cv::Vec2f>(y + 1) + 1;
    int* idrow = zb.ids.data() + static_cast<std::size_t>(y) * zb.w;
    float* zrow = zb.z.data() + static_cast<std::size_t>(y) * zb.w;
    for (int x = xa; x <= xb; ++x) {
      double z = 0.0;
      if (!hit(f, static_cast<double>(rrow[x][0]), static_cast<double>(rrow[x][1]), z)) continue;
      if (z < zrow[x]) {
        zrow[x] = static_cast<float>(z);
        idrow[x] = k;
      }
    }
  }
}

/// Z-buffer pass over `region` (ids and depths there must be cleared).
void fill_zbuffer(const std::vector<Surface>& surfaces, const cv::Rect& region, const cv::Mat& rays, ZBuffer& zb) {
  for (std::size_t k = 0; k < surfaces.size(); ++k) {
    const Surface& f = surfaces[k];
    const int id = static_cast<int>(k);
    switch (f.kind) {
      case SurfaceKind::kPolygon:
        raster(f, id, region, rays, zb,
               [](const Surface& s, double x, double y, double& z) { return s.hit_polygon(x, y, z); });
        break;
      case SurfaceKind::kDisk:
        raster(f, id, region, rays, zb,
               [](const Surface& s, double x, double y, double& z) { return s.hit_disk(x, y, z); });
        break;
      case SurfaceKind::kCylinderSide:
        raster(f, id, region, rays, zb,
               [](const Surface& s, double x, double y, double& z) { return s.hit_side(x, y, z); });
        break;
    }
  }
}

/// \brief Colour (BGR, grey levels, before shadow, occluder and noise) of surfaces and background
/// in one frame.
class Shader {
 public:
  Shader(const cv::Mat& rays, const cv::Mat& background, const std::vector<cv::Point2f>& offsets, const float* texture,
         const RenderOptions& opt, const FrameLighting& lighting)
      : rays_(rays),
        background_(background),
        offsets_(offsets),
        tex_(texture),
        tex_s_(static_cast<float>(std::clamp(opt.texture_strength, 0.0, 1.0))),
        ambient_(opt.ambient),
        L_(lighting) {}

  [[nodiscard]] Eigen::Vector3f background(int x, int y) const {
    const cv::Vec3f& b = background_.ptr<cv::Vec3f>(y)[x];
    return Eigen::Vector3f(b[0], b[1], b[2]) * L_.gain;
  }

  /// Colour of surface `f` seen along the ray (rx, ry) (normalised coordinates; the ray hits f).
  [[nodiscard]] Eigen::Vector3f surface(const Surface& f, double rx, double ry) const {
    const bool need_tex = tex_s_ > 0.0f || L_.specular;
    Eigen::Vector3f a = f.albedo;
    float light = f.light;
    Eigen::Vector3d p = Eigen::Vector3d::Zero(), normal = f.n;
    double u = 0, v = 0, fade = -1.0;  // texture coordinates; fade >= 0: cross-fade of the side's seam
    if (f.kind == SurfaceKind::kCylinderSide) {
      double z = 0.0;
      (void)f.hit_side(rx, ry, z);
      p = Eigen::Vector3d(rx * z, ry * z, z);
      const double h = p.dot(f.axis) - f.a_axis;
      const Eigen::Vector3d rel = p - f.a - h * f.axis;
      normal = rel / f.radius;
      light = static_cast<float>(ambient_ + (1.0 - ambient_) * std::max(0.0, normal.dot(L_.light)));
      if (need_tex) {
        fade = std::atan2(rel.dot(f.e2), rel.dot(f.e1)) / (2.0 * std::numbers::pi) + 0.5;  // [0, 1]
        u = f.tex_around * fade + f.tu0;
        v = f.tex_per_m * h + f.tv0;
      }
    } else if (need_tex) {
      const double z = f.plane_depth(rx, ry);
      p = Eigen::Vector3d(rx * z, ry * z, z);
      u = f.tu.dot(p) + f.tu0;
      v = f.tv.dot(p) + f.tv0;
    }
    // The side's angular coordinate wraps: blend two copies so that the texture is continuous.
    auto lookup = [&](double scale, double du, double dv) -> float {
      const float t0 = detail::texture_at(tex_, scale * u + du, scale * v + dv);
      if (fade < 0.0) return t0;
      const float t1 = detail::texture_at(tex_, scale * (u - f.tex_around) + du, scale * v + dv);
      return static_cast<float>(1.0 - fade) * t0 + static_cast<float>(fade) * t1;
    };
    float rust = 0.0f;
    if (tex_s_ > 0.0f) {
      const float n = lookup(1.0, 0.0, 0.0);
      // Mottled steel, with rust where the fBm is high.
      rust = detail::smoothstep(kRustFrom, kRustTo, n) * kRustMax * tex_s_;
      a = (a * (1.0f + kMottle * tex_s_ * (n - 0.5f))) * (1.0f - rust) + kRust * rust;
    }
    Eigen::Vector3f c = (a * (255.0f * light)) * L_.gain;
    if (L_.specular) {
      const Eigen::Vector3d half = (L_.spec_light - p.normalized()).normalized();
      const double ndh = normal.dot(half);
      if (ndh > 0.0) {
        const float glint = detail::smoothstep(kGlintFrom, kGlintTo, lookup(kGlintScale, 131.0, 71.0));
        const float lobe = static_cast<float>(std::pow(ndh, static_cast<double>(L_.shininess)));
        const float s =
            L_.spec_strength * lobe * (L_.sheen + (1.0f - L_.sheen) * glint) * (1.0f - rust) * 255.0f * L_.gain;
        c += Eigen::Vector3f::Constant(s);
      }
    }
    return c;
  }

  /// Shades every pixel of `region` from the z-buffer of `surfaces` and calls emit(x, y, colour).
  template <typename Emit>
  void shade(const std::vector<Surface>& surfaces, const ZBuffer& zb, const cv::Rect& region, Emit&& emit) const {
    const int w = zb.w, h = static_cast<int>(zb.ids.size()) / std::max(w, 1);
    const int ns = static_cast<int>(offsets_.size());
    const float inv_ns = 1.0f / static_cast<float>(ns);
    std::vector<int> candidates;
    candidates.reserve(surfaces.size());
    for (int y = region.y; y < region.y + region.height; ++y) {
      const auto* rrow = rays_.ptr<cv::Vec2f>(y + 1) + 1;
      const int* idrow = zb.ids.data() + static_cast<std::size_t>(y) * w;
      const int* idup = y > 0 ? idrow - w : idrow;
      const int* iddown = y + 1 < h ? idrow + w : idrow;
      for (int x = region.x; x < region.x + region.width; ++x) {
        const int id = idrow[x];
        // A straight boundary that crosses a pixel's square separates its centre from one of
        // its 4-neighbours' centres, so these are the pixels that need supersampling.
        const bool edge = ns > 1 && ((x > 0 && idrow[x - 1] != id) || (x + 1 < w && idrow[x + 1] != id) ||
                                     idup[x] != id || iddown[x] != id);
        Eigen::Vector3f c;
        if (!edge) {
          c = id < 0 ? background(x, y)
                     : surface(surfaces[static_cast<std::size_t>(id)], static_cast<double>(rrow[x][0]),
                               static_cast<double>(rrow[x][1]));
        } else {
          candidates.clear();
          for (std::size_t k = 0; k < surfaces.size(); ++k)
            if (surfaces[k].in_box(x, y)) candidates.push_back(static_cast<int>(k));
          const Eigen::Vector3f bg = background(x, y);
          c.setZero();
          for (const cv::Point2f& o : offsets_) {
            // Bilinear interpolation of the ray table (the undistortion map is smooth).
            const float fu = static_cast<float>(x + 1) + o.x, fv = static_cast<float>(y + 1) + o.y;
            const int iu = static_cast<int>(std::floor(fu)), iv = static_cast<int>(std::floor(fv));
            const float au = fu - static_cast<float>(iu), av = fv - static_cast<float>(iv);
            const auto* r0 = rays_.ptr<cv::Vec2f>(iv);
            const auto* r1 = rays_.ptr<cv::Vec2f>(iv + 1);
            const cv::Vec2f top = r0[iu] * (1.0f - au) + r0[iu + 1] * au;
            const cv::Vec2f bot = r1[iu] * (1.0f - au) + r1[iu + 1] * au;
            const cv::Vec2f r = top * (1.0f - av) + bot * av;
            int best = -1;
            double best_z = std::numeric_limits<double>::infinity();
            for (int k : candidates) {
              double z = 0.0;
              if (!surfaces[static_cast<std::size_t>(k)].hit(r[0], r[1], z)) continue;
              if (z < best_z) {
                best_z = z;
                best = k;
              }
            }
            c += best < 0 ? bg : surface(surfaces[static_cast<std::size_t>(best)], r[0], r[1]);
          }
          c *= inv_ns;
        }
        emit(x, y, c);
      }
    }
  }

 private:
  const cv::Mat& rays_;
  const cv::Mat& background_;
  const std::vector<cv::Point2f>& offsets_;
  const float* tex_;
  float tex_s_;
  double ambient_;
  FrameLighting L_;
};

cv::Rect surface_box(const Surface& f) { return {f.x0, f.y0, f.x1 - f.x0 + 1, f.y1 - f.y0 + 1}; }

}  // namespace

Renderer::Renderer(const geometry::PinholeCamera& cam, const RenderOptions& opt) : cam_(cam), opt_(opt) {
  const int w = std::max(cam_.width, 1), h = std::max(cam_.height, 1);
  cam_.width = w;
  cam_.height = h;
  opt_.supersample = std::max(opt_.supersample, 1);
  opt_.blur_samples = std::max(opt_.blur_samples, 1);

  // Ray table with a one-pixel border, so that sub-pixel samples interpolate inside it.
  rays_.create(h + 2, w + 2, CV_32FC2);
  double xmin = std::numeric_limits<double>::max(), ymin = xmin, xmax = -xmin, ymax = -xmin;
  for (int y = -1; y <= h; ++y) {
    auto* row = rays_.ptr<cv::Vec2f>(y + 1);
    Eigen::Vector2d r((-1.0 - cam_.cx) / cam_.fx, (y - cam_.cy) / cam_.fy);
    for (int x = -1; x <= w; ++x) {
      r = undistort(cam_, Eigen::Vector2d(x, y), r);
      row[x + 1] = cv::Vec2f(static_cast<float>(r.x()), static_cast<float>(r.y()));
      xmin = std::min(xmin, r.x());
      xmax = std::max(xmax, r.x());
      ymin = std::min(ymin, r.y());
      ymax = std::max(ymax, r.y());
    }
  }
  const double mx = kRayBoundsMargin * (xmax - xmin) + 1e-6, my = kRayBoundsMargin * (ymax - ymin) + 1e-6;
  ray_bounds_ = cv::Rect2d(xmin - mx, ymin - my, xmax - xmin + 2 * mx, ymax - ymin + 2 * my);

  // Sub-pixel samples: an S x S grid sheared so that all S^2 samples have distinct x and
  // distinct y offsets (steps of 1/S^2 px), which resolves near-axis-aligned edges finely.
  const int s = opt_.supersample;
  for (int j = 0; j < s; ++j) {
    for (int i = 0; i < s; ++i) {
      const double ox = (i + (j + 0.5) / s) / s - 0.5;
      const double oy = (j + (i + 0.5) / s) / s - 0.5;
      sample_offsets_.emplace_back(static_cast<float>(ox), static_cast<float>(oy));
    }
  }

  // Surface texture: periodic fBm, three octaves with cells of 16, 8 and 4 texels.
  texture_.resize(static_cast<std::size_t>(kTextureSize) * kTextureSize);
  {
    const std::uint64_t key = splitmix64(0x7E8700000ull + opt_.seed);
    const detail::ValueNoise2D o1(key + 1, kTextureSize / 16, kTextureSize / 16),
        o2(key + 2, kTextureSize / 8, kTextureSize / 8), o3(key + 3, kTextureSize / 4, kTextureSize / 4);
    for (int y = 0; y < kTextureSize; ++y)
      for (int x = 0; x < kTextureSize; ++x)
        texture_[static_cast<std::size_t>(y) * kTextureSize + x] = static_cast<float>(
            0.55 * o1(x / 16.0, y / 16.0) + 0.30 * o2(x / 8.0, y / 8.0) + 0.15 * o3(x / 4.0, y / 4.0));
  }

  occluder_ = detail::default_occluder_layout(opt_.occluder, w, h);

  // Static background: a large-scale undulation, a few soft blobs and a faint grain.
  clean_background_.create(h, w, CV_32FC3);
  const double g0 = opt_.background_grey;
  if (!opt_.textured_background) {
    clean_background_.setTo(cv::Scalar(g0, g0, g0));
  } else {
    const std::uint64_t key = splitmix64(0xBAC6000000ull + opt_.seed);
    struct Layer {
      detail::ValueNoise2D noise;
      double cell, amp;  // pixels, grey levels (peak to peak)
    };
    const std::vector<Layer> layers{{detail::ValueNoise2D(key + 1, w / 140 + 2, h / 140 + 2), 140.0, 16.0},
                                    {detail::ValueNoise2D(key + 2, w / 23 + 2, h / 23 + 2), 23.0, 6.0},
                                    {detail::ValueNoise2D(key + 3, w / 4 + 2, h / 4 + 2), 4.0, 3.0}};
    const detail::ValueNoise2D tint(key + 4, w / 90 + 2, h / 90 + 2);
    struct Blob {
      double x, y, sigma, amp;
    };
    std::vector<Blob> blobs;
    for (int i = 0; i < 7; ++i) {
      blobs.push_back(Blob{unit_hash(key, 4 * i) * w, unit_hash(key, 4 * i + 1) * h,
                           25.0 + 70.0 * unit_hash(key, 4 * i + 2), 20.0 * (unit_hash(key, 4 * i + 3) - 0.5)});
    }
    for (int y = 0; y < h; ++y) {
      auto* row = clean_background_.ptr<cv::Vec3f>(y);
      for (int x = 0; x < w; ++x) {
        double v = g0;
        for (const Layer& l : layers) v += l.amp * (l.noise(x / l.cell, y / l.cell) - 0.5);
        for (const Blob& b : blobs) {
          const double r2 = ((x - b.x) * (x - b.x) + (y - b.y) * (y - b.y)) / (b.sigma * b.sigma);
          if (r2 < 16.0) v += b.amp * std::exp(-0.5 * r2);
        }
        const double warm = 2.0 + 3.0 * (tint(x / 90.0, y / 90.0) - 0.5);  // slightly brownish floor
        row[x] = cv::Vec3f(static_cast<float>(v - warm), static_cast<float>(v), static_cast<float>(v + warm));
      }
    }
  }
  if (opt_.clutter.enabled) detail::draw_random_clutter(clean_background_, opt_.clutter, opt_.seed);
  background_ = clean_background_;
}

namespace {

/// CV_8UC1 mask (255) of the pixel centres where the model is the nearest surface.
cv::Mat mask_of(const ZBuffer& zb, int w, int h) {
  cv::Mat m(h, w, CV_8UC1);
  for (int y = 0; y < h; ++y) {
    auto* row = m.ptr<std::uint8_t>(y);
    const int* ids = zb.ids.data() + static_cast<std::size_t>(y) * w;
    for (int x = 0; x < w; ++x) row[x] = ids[x] >= 0 ? 255 : 0;
  }
  return m;
}

}  // namespace

void Renderer::set_scene_reference(const model::Model& model, const std::vector<geometry::SE3>& trajectory) {
  if (trajectory.empty() || (!opt_.clutter.enabled && !opt_.occluder.enabled)) return;
  const int w = cam_.width, h = cam_.height;
  const detail::SurfaceSetup setup{&cam_, ray_bounds_, kTexelsPerScale / std::max(opt_.texture_scale, 1e-6), opt_.seed};
  auto mask_at = [&](const geometry::SE3& T) {
    ZBuffer zb(w, h);
    fill_zbuffer(detail::build_surfaces(model, T, setup), cv::Rect(0, 0, w, h), rays_, zb);
    return mask_of(zb, w, h);
  };
  const cv::Mat first = mask_at(trajectory.front());
  if (opt_.clutter.enabled) {
    background_ = clean_background_.clone();
    detail::draw_near_clutter(background_, first, opt_.clutter, opt_.seed);
  }
  if (opt_.occluder.enabled) {
    const std::size_t peak = std::min(static_cast<std::size_t>(detail::cycle_frames(opt_) / 2), trajectory.size() - 1);
    occluder_ = detail::layout_occluder(opt_.occluder, first, mask_at(trajectory[peak]));
  }
}

cv::Mat Renderer::render(const model::Model& model, const geometry::SE3& T_cam_obj, int frame_index,
                         const geometry::SE3* T_prev, FrameInfo* info) const {
  const int w = cam_.width, h = cam_.height;
  const cv::Rect full(0, 0, w, h);
  const FrameLighting lighting = detail::lighting_at(opt_, frame_index);
  const ShadowState shadow = detail::shadow_at(opt_, frame_index, w, h);
  const OccluderState occluder = detail::occluder_at(opt_, occluder_, frame_index);
  const Shader shader(rays_, background_, sample_offsets_, texture_.data(), opt_, lighting);
  const detail::SurfaceSetup setup{&cam_, ray_bounds_, kTexelsPerScale / std::max(opt_.texture_scale, 1e-6), opt_.seed};
  auto surfaces_at = [&](const geometry::SE3& T) {
    std::vector<Surface> s = detail::build_surfaces(model, T, setup);
    detail::light_surfaces(s, lighting.light, opt_.ambient);
    return s;
  };

  // Occluder: the columns each row may cover.
  std::vector<std::pair<int, int>> occ_span(static_cast<std::size_t>(h), {0, -1});
  if (occluder.on)
    for (int y = 0; y < h; ++y) {
      auto& [xa, xb] = occ_span[static_cast<std::size_t>(y)];
      if (!occluder.row_span(y, w, xa, xb)) xb = -1;
    }
  if (info) info->occluder_mask = cv::Mat::zeros(h, w, CV_8UC1);

  // Sensor noise, impulse noise and quantisation.
  const std::uint64_t noise_key =
      splitmix64((static_cast<std::uint64_t>(opt_.seed) << 32) ^ static_cast<std::uint32_t>(frame_index));
  const std::uint64_t impulse_key = splitmix64(noise_key ^ 0x5A175E99E2ull);
  const float sigma = static_cast<float>(std::max(opt_.noise_sigma, 0.0));
  const double impulse = std::clamp(opt_.salt_pepper, 0.0, 1.0);
  // Approximately Gaussian: a scaled sum of four 16-bit uniforms (variance 4/12).
  auto noise = [&](std::uint64_t i) -> float {
    const std::uint64_t r = splitmix64(noise_key + i * 0x9E3779B97F4A7C15ull);
    const float sum = static_cast<float>((r & 0xFFFF) + ((r >> 16) & 0xFFFF) + ((r >> 32) & 0xFFFF) + (r >> 48));
    return (sum * (1.0f / 65536.0f) - 2.0f) * 1.7320508f * sigma;
  };
  auto quantise = [](float v) { return static_cast<std::uint8_t>(std::clamp(v + 0.5f, 0.0f, 255.0f)); };

  cv::Mat result(h, w, opt_.colour ? CV_8UC3 : CV_8UC1);
  const float* tex = texture_.data();
  // Shadow, occluder, noise, quantisation of pixel (x, y) with scene colour c.
  auto finish = [&](int x, int y, Eigen::Vector3f c) {
    if (shadow.on) c *= shadow.factor(x, y);
    if (occluder.on) {
      const auto& [xa, xb] = occ_span[static_cast<std::size_t>(y)];
      if (x >= xa && x <= xb) {
        double along = 0, across = 0;
        const double dist = occluder.distance(x, y, along, across);
        const float a = occluder.coverage(dist);
        if (a > 0.0f) c = c * (1.0f - a) + occluder.colour(tex, along, across) * (lighting.gain * a);
        if (info && dist <= occluder.layout.radius_px) info->occluder_mask.ptr<std::uint8_t>(y)[x] = 255;
      }
    }
    const std::uint64_t i = static_cast<std::uint64_t>(y) * w + x;
    auto* out = result.ptr<std::uint8_t>(y);
    int impulse_value = -1;
    if (impulse > 0.0) {
      const std::uint64_t r = splitmix64(impulse_key + i * 0xD1B54A32D192ED03ull);
      if (static_cast<double>(r >> 11) * 0x1.0p-53 < impulse) impulse_value = (r & 1) ? 255 : 0;
    }
    if (opt_.colour) {
      if (sigma > 0.0f) c += Eigen::Vector3f(noise(3 * i), noise(3 * i + 1), noise(3 * i + 2));
      out[3 * x + 0] = quantise(c.x());
      out[3 * x + 1] = quantise(c.y());
      out[3 * x + 2] = quantise(c.z());
      if (impulse_value >= 0) out[3 * x] = out[3 * x + 1] = out[3 * x + 2] = static_cast<std::uint8_t>(impulse_value);
    } else {
      float g = 0.114f * c.x() + 0.587f * c.y() + 0.299f * c.z();
      if (sigma > 0.0f) g += noise(i);
      out[x] = impulse_value >= 0 ? static_cast<std::uint8_t>(impulse_value) : quantise(g);
    }
  };

  const int K = T_prev ? opt_.blur_samples : 1;
  if (K <= 1) {
    const std::vector<Surface> surfaces = surfaces_at(T_cam_obj);
    ZBuffer zb(w, h);
    fill_zbuffer(surfaces, full, rays_, zb);
    shader.shade(surfaces, zb, full, finish);
    if (info) info->object_mask = mask_of(zb, w, h);
    return result;
  }

  // Motion blur: sub-frame poses T_k = exp(s_k xi) T_prev with xi = log(T T_prev^-1), at the
  // middle of K equal parts of the exposure, which ends at s = 1 (T_cam_obj).
  const geometry::Vector6d xi = (T_cam_obj * T_prev->inverse()).log();
  const double exposure = std::clamp(opt_.blur_exposure, 0.0, 1.0);
  std::vector<std::vector<Surface>> subs;
  cv::Rect swept;
  for (int k = 0; k < K; ++k) {
    const double s = 1.0 - exposure * (k + 0.5) / K;
    subs.push_back(surfaces_at(geometry::SE3::exp(s * xi) * *T_prev));
    for (const Surface& f : subs.back()) swept = swept.area() > 0 ? (swept | surface_box(f)) : surface_box(f);
  }
  swept &= full;
  cv::Mat acc = cv::Mat::zeros(std::max(swept.height, 1), std::max(swept.width, 1), CV_32FC3);
  ZBuffer zb(w, h);
  for (const std::vector<Surface>& surfaces : subs) {
    zb.clear(swept);
    fill_zbuffer(surfaces, swept, rays_, zb);
    shader.shade(surfaces, zb, swept, [&](int x, int y, const Eigen::Vector3f& c) {
      acc.ptr<cv::Vec3f>(y - swept.y)[x - swept.x] += cv::Vec3f(c.x(), c.y(), c.z());
    });
  }
  const float inv_k = 1.0f / static_cast<float>(K);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (swept.contains(cv::Point(x, y))) {
        const cv::Vec3f& a = acc.ptr<cv::Vec3f>(y - swept.y)[x - swept.x];
        finish(x, y, Eigen::Vector3f(a[0], a[1], a[2]) * inv_k);
      } else {
        finish(x, y, shader.background(x, y));
      }
    }
  }
  if (info) {
    ZBuffer at_pose(w, h);
    fill_zbuffer(surfaces_at(T_cam_obj), full, rays_, at_pose);
    info->object_mask = mask_of(at_pose, w, h);
  }
  return result;
}

}  // namespace v4r::synth
