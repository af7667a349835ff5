// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/template_set.hpp"

#include <algorithm>
#include <cmath>

#include "v4r/detection/edge_projection.hpp"
#include "v4r/detection/gradient_pyramid.hpp"
#include "v4r/geometry/look_at.hpp"

namespace v4r::detection {

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

/// Whether grid index k (of n) carries a coarse template with the given stride: every stride-th
/// index, and the last one when the stride leaves it more than one step from a coarse index.
bool on_coarse(int k, int n, int stride) {
  if (k % stride == 0) return true;
  return k == n - 1 && (n - 1) % stride > stride / 2;
}

/// `n` values evenly from lo to hi (n = 1: lo).
double lin(double lo, double hi, int k, int n) { return n <= 1 ? lo : lo + (hi - lo) * k / (n - 1); }

/// Samples of one level: offsets at `scale`, quantised orientations, consecutive duplicates
/// merged, then `wanted` of them taken evenly along the edges.
void add_template(TemplateLevel& level, const std::vector<EdgeSample>& samples, std::size_t n, int wanted,
                  std::vector<Feature>& scratch) {
  scratch.clear();
  for (std::size_t i = 0; i < n; ++i) {
    const EdgeSample& s = samples[i];
    Feature f;
    f.x = static_cast<std::int16_t>(std::lround(s.px.x() * level.scale));
    f.y = static_cast<std::int16_t>(std::lround(s.px.y() * level.scale));
    f.orientation = static_cast<std::uint8_t>(quantise_orientation(s.normal.x(), s.normal.y()));
    if (!scratch.empty() && scratch.back().x == f.x && scratch.back().y == f.y && scratch.back().orientation == f.orientation)
      continue;
    scratch.push_back(f);
  }
  Template t;
  t.first = static_cast<std::uint32_t>(level.features.size());
  const std::size_t m = scratch.size();
  const std::size_t take = std::min<std::size_t>(m, static_cast<std::size_t>(wanted));
  for (std::size_t k = 0; k < take; ++k) {
    const Feature& f = scratch[(k * m) / take + (m / take) / 2];
    level.features.push_back(f);
    if (k == 0) {
      t.x0 = t.x1 = f.x;
      t.y0 = t.y1 = f.y;
    }
    t.x0 = std::min(t.x0, f.x);
    t.x1 = std::max(t.x1, f.x);
    t.y0 = std::min(t.y0, f.y);
    t.y1 = std::max(t.y1, f.y);
  }
  t.count = static_cast<std::uint32_t>(take);
  level.templates.push_back(t);
}

}  // namespace

ModelExtent model_extent(const model::Model& model) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  std::vector<Eigen::Vector3d> pts;
  for (const auto& j : model.junctions()) pts.push_back(j.p);
  for (const auto& c : model.cylinders())
    for (const Eigen::Vector3d& q : {c.p1, c.p2})
      for (int k = 0; k < 8; ++k)
        pts.push_back(q + c.radius * Eigen::Vector3d(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1));
  for (const auto& a : model.arcs())
    for (int k = 0; k < 8; ++k)
      pts.push_back(a.center + a.radius * Eigen::Vector3d(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1));
  ModelExtent e;
  if (pts.empty()) return e;
  for (const auto& q : pts) {
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  e.centre = 0.5 * (lo + hi);
  // Junctions give the radius; rims count by their true extent (radius from the centre line).
  for (const auto& j : model.junctions()) e.radius = std::max(e.radius, (j.p - e.centre).norm());
  for (const auto& a : model.arcs()) e.radius = std::max(e.radius, (a.center - e.centre).norm() + a.radius);
  return e;
}

Expected<TemplateSet> build_templates(const model::Model& model, const geometry::PinholeCamera& cam,
                                      const DetectorParams& p, const BuildProgress& progress) {
  if (auto ok = validate(p); !ok) return ok.error();
  if (!(cam.fx > 0.0) || !(cam.fy > 0.0)) return make_error("camera: focal lengths must be positive");
  if (model.junctions().empty() || (model.lines().empty() && model.arcs().empty()))
    return make_error("model has no edges to build templates from");
  const ModelExtent ext = model_extent(model);
  const ViewRange v = resolve_view_range(p.views, ext.radius, cam.focal());
  const TemplateParams& tp = p.templates;
  TemplateSet set;
  set.centre = ext.centre;
  set.fx = cam.fx;
  set.fy = cam.fy;
  const double el_span = v.elevation_max_deg - v.elevation_min_deg;
  set.n_elevation = el_span <= 0 ? 1 : static_cast<int>(std::ceil(el_span / tp.view_step_deg - 1e-9)) + 1;
  const double az_span = v.azimuth_max_deg - v.azimuth_min_deg;
  set.azimuth_wraps = az_span >= 360.0 - 1e-9;
  if (set.azimuth_wraps) {
    set.n_azimuth = std::max(3, static_cast<int>(std::ceil(360.0 / tp.view_step_deg - 1e-9)));
  } else {
    set.n_azimuth = az_span <= 0 ? 1 : static_cast<int>(std::ceil(az_span / tp.view_step_deg - 1e-9)) + 1;
  }
  const double ip_span = v.inplane_max_deg - v.inplane_min_deg;
  set.n_inplane = ip_span <= 0 ? 1 : static_cast<int>(std::ceil(ip_span / tp.inplane_step_deg - 1e-9)) + 1;
  const double d_ratio = v.distance_max_m / v.distance_min_m;
  set.n_distance = d_ratio <= 1.0 + 1e-9 ? 1 : static_cast<int>(std::ceil(std::log(d_ratio) / std::log(tp.scale_step) - 1e-9)) + 1;
  const std::size_t total = static_cast<std::size_t>(set.n_elevation) * set.n_azimuth * set.n_inplane * set.n_distance;
  if (total > 2000000) return make_error("detect.views: the view range gives more than 2 million templates; narrow it or take larger steps");

  geometry::PinholeCamera tcam;  // template camera: no size, principal point at the origin
  tcam.fx = cam.fx;
  tcam.fy = cam.fy;
  EdgeProjector projector(model, tp.crease_angle_deg * kDeg);
  std::vector<EdgeSample> samples(8192);
  std::vector<Feature> scratch;
  set.fine.scale = 0.5;
  set.coarse.scale = 0.25;
  set.views.reserve(total);
  set.fine.templates.reserve(total);
  std::size_t done = 0;
  for (int is = 0; is < set.n_distance; ++is) {
    const double dist = v.distance_min_m * std::pow(d_ratio, set.n_distance <= 1 ? 0.0 : static_cast<double>(is) / (set.n_distance - 1));
    for (int ie = 0; ie < set.n_elevation; ++ie) {
      const double el = lin(v.elevation_min_deg, v.elevation_max_deg, ie, set.n_elevation) * kDeg;
      for (int ia = 0; ia < set.n_azimuth; ++ia) {
        const double az = set.azimuth_wraps ? (v.azimuth_min_deg + 360.0 * ia / set.n_azimuth) * kDeg
                                            : lin(v.azimuth_min_deg, v.azimuth_max_deg, ia, set.n_azimuth) * kDeg;
        const geometry::SE3 base = geometry::look_at(dist, az, el, set.centre);
        for (int ii = 0; ii < set.n_inplane; ++ii) {
          const double ip = lin(v.inplane_min_deg, v.inplane_max_deg, ii, set.n_inplane) * kDeg;
          const geometry::SE3 roll = geometry::SE3::from_rvec(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, ip));
          TemplateView tv;
          tv.T_cam_obj = roll * base;
          tv.elevation = static_cast<std::int16_t>(ie);
          tv.azimuth = static_cast<std::int16_t>(ia);
          tv.inplane = static_cast<std::int16_t>(ii);
          tv.distance = static_cast<std::int16_t>(is);
          // Dense samples: 1 px apart at 1/2 resolution.
          const std::size_t n = projector.sample(tv.T_cam_obj, tcam, 2.0, samples, -1.0);
          add_template(set.fine, samples, n, tp.fine_features, scratch);
          const int st = tp.coarse_stride;
          const bool is_coarse = on_coarse(ie, set.n_elevation, st) && on_coarse(ia, set.n_azimuth, st) &&
                                 on_coarse(ii, set.n_inplane, st) && on_coarse(is, set.n_distance, st);
          if (is_coarse) {
            set.coarse_views.push_back(static_cast<std::uint32_t>(set.views.size()));
            add_template(set.coarse, samples, n, tp.coarse_features, scratch);
          }
          set.views.push_back(tv);
          ++done;
          if (progress && (done % 64 == 0 || done == total)) progress(done, total);
        }
      }
    }
  }
  // Children of every coarse view: the fine views within stride / 2 grid steps along each axis.
  set.child_offsets.push_back(0);
  const int reach = std::max(1, tp.coarse_stride / 2);
  for (const std::uint32_t cv : set.coarse_views) {
    const TemplateView& c = set.views[cv];
    for (int ds = -reach; ds <= reach; ++ds)
      for (int de = -reach; de <= reach; ++de)
        for (int da = -reach; da <= reach; ++da)
          for (int di = -reach; di <= reach; ++di) {
            const int s = c.distance + ds, e = c.elevation + de, i = c.inplane + di;
            int a = c.azimuth + da;
            if (set.azimuth_wraps) a = (a + set.n_azimuth) % set.n_azimuth;
            if (s < 0 || s >= set.n_distance || e < 0 || e >= set.n_elevation || a < 0 || a >= set.n_azimuth || i < 0 ||
                i >= set.n_inplane)
              continue;
            if (set.azimuth_wraps && set.n_azimuth <= 2 * reach && da != 0) continue;
            set.children.push_back(static_cast<std::uint32_t>(set.view_index(s, e, a, i)));
          }
    set.child_offsets.push_back(static_cast<std::uint32_t>(set.children.size()));
  }
  std::size_t usable = 0;
  for (const Template& t : set.coarse.templates) usable += t.count >= 4 ? 1 : 0;
  if (usable == 0) return make_error("detect.views: no view of the model shows enough edges for a template");
  return set;
}

geometry::SE3 pose_at_pixel(const TemplateSet& set, std::uint32_t view, const geometry::PinholeCamera& cam, double u,
                            double v) {
  const geometry::SE3& T = set.views[view].T_cam_obj;
  const Eigen::Vector2d xn = cam.pixel_to_normalized(Eigen::Vector2d(u, v));
  const Eigen::Vector3d ray = Eigen::Vector3d(xn.x(), xn.y(), 1.0).normalized();
  const Eigen::Quaterniond q = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), ray);
  return geometry::SE3(q, Eigen::Vector3d::Zero()) * T;
}

}  // namespace v4r::detection
