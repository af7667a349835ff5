// v4r - robust model-based object tracking. MIT licence.
//
// Surfaces of one frame. A planar polygon projects to a polygon in normalised coordinates, so
// its inside test is 2-D; disks and the cylinder side are intersected analytically. Every
// surface is bounded in pixels from densely sampled boundary points of its distorted projection.
#include "surfaces.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include "procedural.hpp"

namespace v4r::synth::detail {
namespace {

constexpr double kNearZ = 1e-4;          ///< metres: near clipping plane
constexpr int kBoxPad = 2;               ///< pixels added around each surface's bounding box
constexpr double kBoundaryStepPx = 6.0;  ///< spacing of boundary samples when bounding a face
constexpr double kConvexTol = 1e-12;     ///< |cross| below which consecutive edges are collinear
constexpr int kRimSamples = 64;          ///< samples per cylinder rim when bounding its surfaces

/// Steel albedo (BGR, 0..1) of surfaces without a colour attribute, and its per-surface variation.
const Eigen::Vector3f kSteel(0.85f, 0.85f, 0.85f);
constexpr float kSteelVariation = 0.025f;

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
void prepare_inside_test(Surface& f) {
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

/// Pads the box (px0..px1, py0..py1, pixels) by kBoxPad, clips it to the image and stores it.
bool store_box(const geometry::PinholeCamera& cam, double px0, double py0, double px1, double py1, Surface& f) {
  f.x0 = std::max(0, static_cast<int>(std::floor(px0)) - kBoxPad);
  f.y0 = std::max(0, static_cast<int>(std::floor(py0)) - kBoxPad);
  f.x1 = std::min(cam.width - 1, static_cast<int>(std::ceil(px1)) + kBoxPad);
  f.y1 = std::min(cam.height - 1, static_cast<int>(std::ceil(py1)) + kBoxPad);
  return f.x0 <= f.x1 && f.y0 <= f.y1;
}

/// Pixel bounding box of a polygon given in normalised coordinates, from densely sampled
/// boundary points of its distorted projection, restricted to the normalised region `rb` that
/// the image rays cover (outside it a distortion model may fold back). False if it misses.
bool polygon_box(const geometry::PinholeCamera& cam, const cv::Rect2d& rb, const std::vector<Eigen::Vector2d>& poly,
                 Surface& f) {
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
  return store_box(cam, px0, py0, px1, py1, f);
}

/// Pixel bounding box of a convex solid from points of its boundary (camera frame) whose
/// convex hull holds it: each point's normalised coordinates are clamped to `rb` (points beyond
/// the image's rays map to its border). A point behind the near plane gives the whole image.
bool points_box(const geometry::PinholeCamera& cam, const cv::Rect2d& rb, const std::vector<Eigen::Vector3d>& pts,
                Surface& f) {
  double px0 = std::numeric_limits<double>::max(), py0 = px0, px1 = -px0, py1 = -px0;
  for (const Eigen::Vector3d& p : pts) {
    if (p.z() <= kNearZ) return store_box(cam, 0, 0, cam.width - 1, cam.height - 1, f);
    const Eigen::Vector2d xn(std::clamp(p.x() / p.z(), rb.x, rb.x + rb.width),
                             std::clamp(p.y() / p.z(), rb.y, rb.y + rb.height));
    const Eigen::Vector2d q = cam.normalized_to_pixel(xn);
    px0 = std::min(px0, q.x());
    px1 = std::max(px1, q.x());
    py0 = std::min(py0, q.y());
    py1 = std::max(py1, q.y());
  }
  // A box entirely outside the image misses it.
  if (px1 < -0.5 || py1 < -0.5 || px0 > cam.width - 0.5 || py0 > cam.height - 0.5) return false;
  return store_box(cam, px0, py0, px1, py1, f);
}

/// Albedo from a colour attribute (RGB) or steel with a small variation keyed by (key, index).
Eigen::Vector3f albedo_of(const model::Attributes& attr, std::uint64_t key, std::size_t index) {
  if (attr.colour) {
    const Eigen::Vector3f& c = *attr.colour;  // RGB
    return {c.z(), c.y(), c.x()};
  }
  const float v = static_cast<float>(unit_hash(key, index)) * 2.0f - 1.0f;
  return kSteel * (1.0f + kSteelVariation * v);
}

/// Planar texture axes for a surface with object-frame normal `no`, moved to the camera frame:
/// u(p_cam) = a . (R^T (p_cam - t)) = (R a) . p_cam - (R a) . t, plus a random offset.
void planar_texture(Surface& f, const Eigen::Vector3d& no, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                    double texels_per_metre, double off_u, double off_v) {
  const Eigen::Vector3d helper = std::abs(no.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d ua = no.cross(helper).normalized(), va = no.cross(ua);
  f.tu = (R * ua) * texels_per_metre;
  f.tv = (R * va) * texels_per_metre;
  f.tu0 = -f.tu.dot(t) + off_u;
  f.tv0 = -f.tv.dot(t) + off_v;
}

void add_faces(const model::Model& model, const Eigen::Matrix3d& R, const Eigen::Vector3d& t, const SurfaceSetup& s,
               std::vector<Surface>& out) {
  const auto& junctions = model.junctions();
  for (std::size_t fi = 0; fi < model.faces().size(); ++fi) {
    const model::Face& mf = model.faces()[fi];
    if (mf.loop.size() < 3) continue;
    Surface f;
    f.kind = SurfaceKind::kPolygon;
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
    if (!polygon_box(*s.cam, s.ray_bounds, f.poly, f)) continue;
    f.albedo = albedo_of(mf.attr, 0xFACEull + s.seed, fi);
    planar_texture(f, mf.normal, R, t, s.texels_per_metre, kTextureSize * unit_hash(0x7E8Aull + s.seed, 2 * fi),
                   kTextureSize * unit_hash(0x7E8Aull + s.seed, 2 * fi + 1));
    out.push_back(std::move(f));
  }
}

void add_cylinders(const model::Model& model, const Eigen::Matrix3d& R, const Eigen::Vector3d& t, const SurfaceSetup& s,
                   std::vector<Surface>& out) {
  for (std::size_t ci = 0; ci < model.cylinders().size(); ++ci) {
    const model::Cylinder& mc = model.cylinders()[ci];
    const Eigen::Vector3d axis_obj = mc.p2 - mc.p1;
    const double length = axis_obj.norm();
    if (!(length > 0.0) || !(mc.radius > 0.0)) continue;
    const Eigen::Vector3d u_obj = axis_obj / length;
    const Eigen::Vector3d e1_obj = u_obj.unitOrthogonal(), e2_obj = u_obj.cross(e1_obj);
    const Eigen::Vector3d a = R * mc.p1 + t, axis = R * u_obj, e1 = R * e1_obj, e2 = R * e2_obj;
    const Eigen::Vector3f albedo = albedo_of(mc.attr, 0xC1714DE5ull + s.seed, ci);
    auto offset = [&](int k) { return kTextureSize * unit_hash(0x7E8Bull + s.seed, 6 * ci + k); };

    // Rim samples (camera frame) for the bounding boxes.
    std::array<std::vector<Eigen::Vector3d>, 2> rims;
    for (int k = 0; k < kRimSamples; ++k) {
      const double phi = 2.0 * std::numbers::pi * k / kRimSamples;
      const Eigen::Vector3d radial = mc.radius * (std::cos(phi) * e1 + std::sin(phi) * e2);
      rims[0].push_back(a + radial);
      rims[1].push_back(a + length * axis + radial);
    }

    // Side: visible from outside the infinite cylinder only (from inside it, through a cap).
    Surface side;
    side.kind = SurfaceKind::kCylinderSide;
    side.a = a;
    side.axis = axis;
    side.a_axis = a.dot(axis);
    side.q = -a + side.a_axis * axis;
    side.c0 = side.q.squaredNorm() - mc.radius * mc.radius;
    side.length = length;
    side.radius = mc.radius;
    side.e1 = e1;
    side.e2 = e2;
    side.albedo = albedo;
    side.tex_around = s.texels_per_metre * 2.0 * std::numbers::pi * mc.radius;
    side.tex_per_m = s.texels_per_metre;
    side.tu0 = offset(0);
    side.tv0 = offset(1);
    std::vector<Eigen::Vector3d> both = rims[0];
    both.insert(both.end(), rims[1].begin(), rims[1].end());
    if (side.c0 > 0.0 && points_box(*s.cam, s.ray_bounds, both, side)) out.push_back(std::move(side));

    // End disks: at p1 facing -axis, at p2 facing +axis; drawn when facing the camera.
    for (int end = 0; end < 2; ++end) {
      Surface cap;
      cap.kind = SurfaceKind::kDisk;
      const Eigen::Vector3d no = end == 0 ? Eigen::Vector3d(-u_obj) : u_obj;
      cap.n = R * no;
      cap.centre = end == 0 ? a : Eigen::Vector3d(a + length * axis);
      cap.d = cap.n.dot(cap.centre);
      if (cap.d >= 0.0) continue;
      cap.radius2 = mc.radius * mc.radius;
      cap.albedo = albedo;
      planar_texture(cap, no, R, t, s.texels_per_metre, offset(2 + 2 * end), offset(3 + 2 * end));
      if (points_box(*s.cam, s.ray_bounds, rims[static_cast<std::size_t>(end)], cap)) out.push_back(std::move(cap));
    }
  }
}

}  // namespace

std::vector<Surface> build_surfaces(const model::Model& model, const geometry::SE3& T_cam_obj,
                                    const SurfaceSetup& setup) {
  const Eigen::Matrix3d R = T_cam_obj.rotation();
  const Eigen::Vector3d t = T_cam_obj.translation();
  std::vector<Surface> out;
  out.reserve(model.faces().size() + 3 * model.cylinders().size());
  add_faces(model, R, t, setup, out);
  add_cylinders(model, R, t, setup, out);
  return out;
}

void light_surfaces(std::vector<Surface>& surfaces, const Eigen::Vector3d& light_unit, double ambient) {
  for (Surface& f : surfaces)
    if (f.kind != SurfaceKind::kCylinderSide)
      f.light = static_cast<float>(ambient + (1.0 - ambient) * std::max(0.0, f.n.dot(light_unit)));
}

}  // namespace v4r::synth::detail
