// v4r - robust model-based object tracking. MIT licence.
//
// Ray-casting renderer.
// Per camera (constructor): the undistorted normalised coordinates of every pixel centre (a ray
// table: undistortion is iterative and too slow per frame), the sub-pixel sample pattern, the
// static background and a periodic fBm texture table.
// Per frame: (1) every front-facing face is moved to the camera frame, clipped at the near
// plane, projected to normalised coordinates (a planar polygon projects to a polygon there, so
// the inside test of a pixel ray is 2-D) and bounded in pixels; (2) a z-buffer pass finds the
// nearest face at every pixel centre; (3) a shading pass shades flat pixels with one sample,
// supersamples the pixels whose 4-neighbours see another surface, adds sensor noise and
// quantises. The surface texture is looked up at the hit point expressed in 2-D coordinates of
// the face's plane in the OBJECT frame, so it moves with the object.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Geometry>

#include "v4r/synth/renderer.hpp"

namespace v4r::synth {
namespace {

constexpr int kTextureSize = 512;          ///< texels per side of the periodic texture table
constexpr double kTexelsPerScale = 16.0;   ///< texels per RenderOptions::texture_scale
constexpr double kNearZ = 1e-4;            ///< metres: near clipping plane
constexpr int kBoxPad = 2;                 ///< pixels added around each face's bounding box
constexpr double kBoundaryStepPx = 6.0;    ///< spacing of boundary samples when bounding a face
constexpr double kRayBoundsMargin = 0.05;  ///< relative margin around the ray table's extent
constexpr int kUndistortMaxIter = 200;     ///< fixed-point iterations per pixel (at most)
constexpr double kUndistortTol = 1e-14;    ///< normalised units: convergence of the undistortion
constexpr double kConvexTol = 1e-12;       ///< |cross| below which consecutive edges are collinear

/// Steel albedo (BGR, 0..1) of faces without a colour attribute, and its per-face variation.
const Eigen::Vector3f kSteel(0.85f, 0.85f, 0.85f);
constexpr float kSteelVariation = 0.025f;
/// Rust albedo (BGR) blended into the steel where the texture's fBm exceeds kRustFrom (fully
/// at kRustTo), at most kRustMax * texture_strength; kMottle * texture_strength is the relative
/// brightness variation of the steel.
const Eigen::Vector3f kRust(0.10f, 0.24f, 0.46f);
constexpr float kRustFrom = 0.45f, kRustTo = 0.80f, kRustMax = 1.0f, kMottle = 1.0f;

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

/// Uniform in [0, 1) from two keys.
double unit_hash(std::uint64_t a, std::uint64_t b) {
  return static_cast<double>(splitmix64(splitmix64(a) ^ (b * 0xD1B54A32D192ED03ull)) >> 11) * 0x1.0p-53;
}

float smoothstep(float e0, float e1, float x) {
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

/// A face ready for ray casting in one frame.
struct FaceCam {
  Eigen::Vector3d n;                   ///< unit normal, camera frame
  double d = 0;                        ///< plane n . p = d (camera frame, metres); d < 0 for front faces
  std::vector<Eigen::Vector2d> poly;   ///< normalised coordinates (after near clipping)
  std::vector<Eigen::Vector3d> lines;  ///< convex case: a x + b y + c >= 0 inside, per edge
  bool convex = true;
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  ///< pixel bounding box (inclusive)
  Eigen::Vector3f albedo;                ///< BGR, 0..1
  float light = 0;                       ///< ambient + diffuse factor
  /// Texture coordinates (texels) of the camera-frame point p: (tu . p + tu0, tv . p + tv0).
  Eigen::Vector3d tu, tv;
  double tu0 = 0, tv0 = 0;

  [[nodiscard]] bool contains(double x, double y) const {
    if (convex) {
      for (const Eigen::Vector3d& l : lines)
        if (l.x() * x + l.y() * y + l.z() < 0.0) return false;
      return true;
    }
    bool in = false;  // crossing number
    for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
      const Eigen::Vector2d& a = poly[i];
      const Eigen::Vector2d& b = poly[j];
      if ((a.y() > y) != (b.y() > y) && x < (b.x() - a.x()) * (y - a.y()) / (b.y() - a.y()) + a.x()) in = !in;
    }
    return in;
  }
  /// Depth (z, metres) where the ray through normalised (x, y) meets the plane.
  [[nodiscard]] double depth(double x, double y) const { return d / (n.x() * x + n.y() * y + n.z()); }
  [[nodiscard]] bool in_box(int x, int y) const { return x >= x0 && x <= x1 && y >= y0 && y <= y1; }
};

/// Clips a polygon to the half-space signed_dist(p) >= 0 (Sutherland-Hodgman, one plane).
template <typename Vec, typename Signed>
std::vector<Vec> clip_polygon(const std::vector<Vec>& in, Signed signed_dist) {
  std::vector<Vec> out;
  if (in.empty()) return out;
  out.reserve(in.size() + 2);
  for (std::size_t i = 0; i < in.size(); ++i) {
    const Vec& a = in[i];
    const Vec& b = in[(i + 1) % in.size()];
    const double da = signed_dist(a), db = signed_dist(b);
    if (da >= 0) out.push_back(a);
    if ((da >= 0) != (db >= 0)) out.push_back(a + (b - a) * (da / (da - db)));
  }
  return out;
}

/// Sets `lines` and `convex` from `poly` (any orientation).
void prepare_inside_test(FaceCam& f) {
  const std::size_t n = f.poly.size();
  double area2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& a = f.poly[i];
    const Eigen::Vector2d& b = f.poly[(i + 1) % n];
    area2 += a.x() * b.y() - b.x() * a.y();
  }
  const double s = area2 >= 0 ? 1.0 : -1.0;
  f.convex = true;
  for (std::size_t i = 0; i < n && f.convex; ++i) {
    const Eigen::Vector2d e0 = f.poly[(i + 1) % n] - f.poly[i];
    const Eigen::Vector2d e1 = f.poly[(i + 2) % n] - f.poly[(i + 1) % n];
    const double cr = e0.x() * e1.y() - e0.y() * e1.x();
    if (s * cr < -kConvexTol * (e0.norm() * e1.norm() + 1e-30)) f.convex = false;
  }
  f.lines.clear();
  if (!f.convex) return;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d& a = f.poly[i];
    const Eigen::Vector2d e = f.poly[(i + 1) % n] - a;
    if (e.squaredNorm() == 0.0) continue;
    // cross(e, p - a) = e.x (py - ay) - e.y (px - ax)
    f.lines.emplace_back(-s * e.y(), s * e.x(), s * (e.y() * a.x() - e.x() * a.y()));
  }
}

/// Pixel bounding box of a polygon given in normalised coordinates, from densely sampled
/// boundary points of its distorted projection, restricted to the normalised region `rb` that
/// the image rays cover (outside it a distortion model may fold back). False if it misses.
bool pixel_box(const geometry::PinholeCamera& cam, const cv::Rect2d& rb, const std::vector<Eigen::Vector2d>& poly,
               FaceCam& f) {
  std::vector<Eigen::Vector2d> bp = poly;
  bp = clip_polygon(bp, [&](const Eigen::Vector2d& p) { return p.x() - rb.x; });
  bp = clip_polygon(bp, [&](const Eigen::Vector2d& p) { return rb.x + rb.width - p.x(); });
  bp = clip_polygon(bp, [&](const Eigen::Vector2d& p) { return p.y() - rb.y; });
  bp = clip_polygon(bp, [&](const Eigen::Vector2d& p) { return rb.y + rb.height - p.y(); });
  if (bp.size() < 3) return false;
  double px0 = std::numeric_limits<double>::max(), py0 = px0, px1 = -px0, py1 = -px0;
  for (std::size_t i = 0; i < bp.size(); ++i) {
    const Eigen::Vector2d& a = bp[i];
    const Eigen::Vector2d& b = bp[(i + 1) % bp.size()];
    const double len_px = (b - a).norm() * std::max(cam.fx, cam.fy);
    const int steps = std::clamp(static_cast<int>(std::ceil(len_px / kBoundaryStepPx)), 1, 256);
    for (int k = 0; k < steps; ++k) {
      const Eigen::Vector2d q = cam.normalized_to_pixel(a + (b - a) * (static_cast<double>(k) / steps));
      px0 = std::min(px0, q.x());
      px1 = std::max(px1, q.x());
      py0 = std::min(py0, q.y());
      py1 = std::max(py1, q.y());
    }
  }
  f.x0 = std::max(0, static_cast<int>(std::floor(px0)) - kBoxPad);
  f.y0 = std::max(0, static_cast<int>(std::floor(py0)) - kBoxPad);
  f.x1 = std::min(cam.width - 1, static_cast<int>(std::ceil(px1)) + kBoxPad);
  f.y1 = std::min(cam.height - 1, static_cast<int>(std::ceil(py1)) + kBoxPad);
  return f.x0 <= f.x1 && f.y0 <= f.y1;
}

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

/// Bilinear lookup in the periodic texture table at texel coordinates (u, v).
float texture_at(const float* tex, double u, double v) {
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

}  // namespace

Renderer::Renderer(const geometry::PinholeCamera& cam, const RenderOptions& opt) : cam_(cam), opt_(opt) {
  const int w = std::max(cam_.width, 1), h = std::max(cam_.height, 1);
  cam_.width = w;
  cam_.height = h;
  opt_.supersample = std::max(opt_.supersample, 1);

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
    const ValueNoise2D o1(key + 1, kTextureSize / 16, kTextureSize / 16),
        o2(key + 2, kTextureSize / 8, kTextureSize / 8), o3(key + 3, kTextureSize / 4, kTextureSize / 4);
    for (int y = 0; y < kTextureSize; ++y)
      for (int x = 0; x < kTextureSize; ++x)
        texture_[static_cast<std::size_t>(y) * kTextureSize + x] = static_cast<float>(
            0.55 * o1(x / 16.0, y / 16.0) + 0.30 * o2(x / 8.0, y / 8.0) + 0.15 * o3(x / 4.0, y / 4.0));
  }

  // Static background: a large-scale undulation, a few soft blobs and a faint grain.
  background_.create(h, w, CV_32FC3);
  const double g0 = opt_.background_grey;
  if (!opt_.textured_background) {
    background_.setTo(cv::Scalar(g0, g0, g0));
    return;
  }
  const std::uint64_t key = splitmix64(0xBAC6000000ull + opt_.seed);
  struct Layer {
    ValueNoise2D noise;
    double cell, amp;  // pixels, grey levels (peak to peak)
  };
  const std::vector<Layer> layers{{ValueNoise2D(key + 1, w / 140 + 2, h / 140 + 2), 140.0, 16.0},
                                  {ValueNoise2D(key + 2, w / 23 + 2, h / 23 + 2), 23.0, 6.0},
                                  {ValueNoise2D(key + 3, w / 4 + 2, h / 4 + 2), 4.0, 3.0}};
  const ValueNoise2D tint(key + 4, w / 90 + 2, h / 90 + 2);
  struct Blob {
    double x, y, sigma, amp;
  };
  std::vector<Blob> blobs;
  for (int i = 0; i < 7; ++i) {
    blobs.push_back(Blob{unit_hash(key, 4 * i) * w, unit_hash(key, 4 * i + 1) * h,
                         25.0 + 70.0 * unit_hash(key, 4 * i + 2), 20.0 * (unit_hash(key, 4 * i + 3) - 0.5)});
  }
  for (int y = 0; y < h; ++y) {
    auto* row = background_.ptr<cv::Vec3f>(y);
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

cv::Mat Renderer::render(const model::Model& model, const geometry::SE3& T_cam_obj, int frame_index) const {
  const int w = cam_.width, h = cam_.height;
  const Eigen::Matrix3d R = T_cam_obj.rotation();
  const Eigen::Vector3d t = T_cam_obj.translation();
  const Eigen::Vector3d light =
      opt_.light_dir_cam.norm() > 0 ? Eigen::Vector3d(opt_.light_dir_cam.normalized()) : Eigen::Vector3d(0, 0, -1);
  const double texels_per_metre = kTexelsPerScale / std::max(opt_.texture_scale, 1e-6);
  const auto& junctions = model.junctions();

  // 1. Faces in the camera frame.
  std::vector<FaceCam> faces;
  faces.reserve(model.faces().size());
  for (std::size_t fi = 0; fi < model.faces().size(); ++fi) {
    const model::Face& mf = model.faces()[fi];
    if (mf.loop.size() < 3) continue;
    FaceCam f;
    f.n = R * mf.normal;
    std::vector<Eigen::Vector3d> pc;
    pc.reserve(mf.loop.size());
    for (model::Index j : mf.loop) pc.push_back(R * junctions[j].p + t);
    f.d = f.n.dot(pc[0]);
    if (f.d >= 0.0) continue;  // back face (or seen edge-on): the camera is behind its plane
    pc = clip_polygon(pc, [](const Eigen::Vector3d& p) { return p.z() - kNearZ; });
    if (pc.size() < 3) continue;
    for (const Eigen::Vector3d& p : pc) f.poly.emplace_back(p.x() / p.z(), p.y() / p.z());
    prepare_inside_test(f);
    if (!pixel_box(cam_, ray_bounds_, f.poly, f)) continue;

    if (mf.attr.colour) {
      const Eigen::Vector3f& c = *mf.attr.colour;  // RGB
      f.albedo = Eigen::Vector3f(c.z(), c.y(), c.x());
    } else {
      const float v = static_cast<float>(unit_hash(0xFACEull + opt_.seed, fi)) * 2.0f - 1.0f;
      f.albedo = kSteel * (1.0f + kSteelVariation * v);
    }
    f.light = static_cast<float>(opt_.ambient + (1.0 - opt_.ambient) * std::max(0.0, f.n.dot(light)));

    // Texture axes in the face plane (object frame), moved to the camera frame:
    // u(p_cam) = a . (R^T (p_cam - t)) = (R a) . p_cam - (R a) . t.
    const Eigen::Vector3d& no = mf.normal;
    const Eigen::Vector3d helper = std::abs(no.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
    const Eigen::Vector3d ua = no.cross(helper).normalized(), va = no.cross(ua);
    f.tu = (R * ua) * texels_per_metre;
    f.tv = (R * va) * texels_per_metre;
    f.tu0 = -f.tu.dot(t) + kTextureSize * unit_hash(0x7E8Aull + opt_.seed, 2 * fi);
    f.tv0 = -f.tv.dot(t) + kTextureSize * unit_hash(0x7E8Aull + opt_.seed, 2 * fi + 1);
    faces.push_back(std::move(f));
  }

  // 2. Z-buffer at the pixel centres.
  std::vector<int> ids(static_cast<std::size_t>(w) * h, -1);
  std::vector<float> zbuf(ids.size(), std::numeric_limits<float>::infinity());
  for (std::size_t k = 0; k < faces.size(); ++k) {
    const FaceCam& f = faces[k];
    for (int y = f.y0; y <= f.y1; ++y) {
      const auto* rrow = rays_.ptr<cv::Vec2f>(y + 1) + 1;
      int* idrow = ids.data() + static_cast<std::size_t>(y) * w;
      float* zrow = zbuf.data() + static_cast<std::size_t>(y) * w;
      for (int x = f.x0; x <= f.x1; ++x) {
        const double rx = rrow[x][0], ry = rrow[x][1];
        if (!f.contains(rx, ry)) continue;
        const double z = f.depth(rx, ry);
        if (z > 0.0 && z < zrow[x]) {
          zrow[x] = static_cast<float>(z);
          idrow[x] = static_cast<int>(k);
        }
      }
    }
  }

  // 3. Shading, noise and quantisation.
  const float tex_s = static_cast<float>(std::clamp(opt_.texture_strength, 0.0, 1.0));
  const float* tex = texture_.data();
  auto shade = [&](const FaceCam& f, double rx, double ry) -> Eigen::Vector3f {
    Eigen::Vector3f a = f.albedo;
    if (tex_s > 0.0f) {
      const double z = f.depth(rx, ry);
      const Eigen::Vector3d p(rx * z, ry * z, z);
      const float n = texture_at(tex, f.tu.dot(p) + f.tu0, f.tv.dot(p) + f.tv0);
      // Mottled steel, with rust where the fBm is high.
      const float rust = smoothstep(kRustFrom, kRustTo, n) * kRustMax * tex_s;
      a = (a * (1.0f + kMottle * tex_s * (n - 0.5f))) * (1.0f - rust) + kRust * rust;
    }
    return a * (255.0f * f.light);
  };

  const std::uint64_t noise_key =
      splitmix64((static_cast<std::uint64_t>(opt_.seed) << 32) ^ static_cast<std::uint32_t>(frame_index));
  const float sigma = static_cast<float>(std::max(opt_.noise_sigma, 0.0));
  // Approximately Gaussian: a scaled sum of four 16-bit uniforms (variance 4/12).
  auto noise = [&](std::uint64_t i) -> float {
    const std::uint64_t r = splitmix64(noise_key + i * 0x9E3779B97F4A7C15ull);
    const float sum = static_cast<float>((r & 0xFFFF) + ((r >> 16) & 0xFFFF) + ((r >> 32) & 0xFFFF) + (r >> 48));
    return (sum * (1.0f / 65536.0f) - 2.0f) * 1.7320508f * sigma;
  };
  auto quantise = [](float v) { return static_cast<std::uint8_t>(std::clamp(v + 0.5f, 0.0f, 255.0f)); };

  const int ns = static_cast<int>(sample_offsets_.size());
  const float inv_ns = 1.0f / static_cast<float>(ns);
  cv::Mat result(h, w, opt_.colour ? CV_8UC3 : CV_8UC1);
  std::vector<int> candidates;
  candidates.reserve(faces.size());
  for (int y = 0; y < h; ++y) {
    const auto* rrow = rays_.ptr<cv::Vec2f>(y + 1) + 1;
    const auto* bgrow = background_.ptr<cv::Vec3f>(y);
    auto* out = result.ptr<std::uint8_t>(y);
    const int* idrow = ids.data() + static_cast<std::size_t>(y) * w;
    const int* idup = y > 0 ? idrow - w : idrow;
    const int* iddown = y + 1 < h ? idrow + w : idrow;
    for (int x = 0; x < w; ++x) {
      const int id = idrow[x];
      // A straight boundary that crosses a pixel's square separates its centre from one of
      // its 4-neighbours' centres, so these are the pixels that need supersampling.
      const bool edge = ns > 1 && ((x > 0 && idrow[x - 1] != id) || (x + 1 < w && idrow[x + 1] != id) ||
                                   idup[x] != id || iddown[x] != id);
      const Eigen::Vector3f bg(bgrow[x][0], bgrow[x][1], bgrow[x][2]);
      Eigen::Vector3f c;
      if (!edge) {
        c = id < 0 ? bg : shade(faces[static_cast<std::size_t>(id)], rrow[x][0], rrow[x][1]);
      } else {
        candidates.clear();
        for (std::size_t k = 0; k < faces.size(); ++k)
          if (faces[k].in_box(x, y)) candidates.push_back(static_cast<int>(k));
        c.setZero();
        for (const cv::Point2f& o : sample_offsets_) {
          // Bilinear interpolation of the ray table (the undistortion map is smooth).
          const float u = static_cast<float>(x + 1) + o.x, v = static_cast<float>(y + 1) + o.y;
          const int iu = static_cast<int>(std::floor(u)), iv = static_cast<int>(std::floor(v));
          const float au = u - static_cast<float>(iu), av = v - static_cast<float>(iv);
          const auto* r0 = rays_.ptr<cv::Vec2f>(iv);
          const auto* r1 = rays_.ptr<cv::Vec2f>(iv + 1);
          const cv::Vec2f top = r0[iu] * (1.0f - au) + r0[iu + 1] * au;
          const cv::Vec2f bot = r1[iu] * (1.0f - au) + r1[iu + 1] * au;
          const cv::Vec2f r = top * (1.0f - av) + bot * av;
          int best = -1;
          double best_z = std::numeric_limits<double>::infinity();
          for (int k : candidates) {
            const FaceCam& f = faces[static_cast<std::size_t>(k)];
            if (!f.contains(r[0], r[1])) continue;
            const double z = f.depth(r[0], r[1]);
            if (z > 0.0 && z < best_z) {
              best_z = z;
              best = k;
            }
          }
          c += best < 0 ? bg : shade(faces[static_cast<std::size_t>(best)], r[0], r[1]);
        }
        c *= inv_ns;
      }
      const std::uint64_t i = static_cast<std::uint64_t>(y) * w + x;
      if (opt_.colour) {
        if (sigma > 0.0f) c += Eigen::Vector3f(noise(3 * i), noise(3 * i + 1), noise(3 * i + 2));
        out[3 * x + 0] = quantise(c.x());
        out[3 * x + 1] = quantise(c.y());
        out[3 * x + 2] = quantise(c.z());
      } else {
        float g = 0.114f * c.x() + 0.587f * c.y() + 0.299f * c.z();
        if (sigma > 0.0f) g += noise(i);
        out[x] = quantise(g);
      }
    }
  }
  return result;
}

}  // namespace v4r::synth
