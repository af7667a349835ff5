// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/template_cache.hpp"

#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <type_traits>
#include <vector>

#include <fmt/format.h>

#include "v4r/detection/gradient_pyramid.hpp"

namespace v4r::detection {

namespace fs = std::filesystem;

namespace {

constexpr char kMagic[8] = {'V', '4', 'R', 'T', 'P', 'L', 0, 0};
constexpr std::size_t kHeaderSize = 8 + 4 + 4 + 8 + 8 + 8;

struct Fnv {
  std::uint64_t h = 1469598103934665603ull;
  void bytes(const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) {
      h ^= b[i];
      h *= 1099511628211ull;
    }
  }
  template <typename T>
  void add(const T& v) {
    static_assert(std::is_arithmetic_v<T>);
    bytes(&v, sizeof(T));
  }
  void add(const Eigen::Vector3d& v) {
    for (int i = 0; i < 3; ++i) add(v[i]);
  }
};

struct Writer {
  std::string out;
  template <typename T>
  void put(const T& v) {
    static_assert(std::is_arithmetic_v<T>);
    out.append(reinterpret_cast<const char*>(&v), sizeof(T));
  }
};

struct Reader {
  const char* p;
  std::size_t left;
  template <typename T>
  bool get(T& v) {
    if (left < sizeof(T)) return false;
    std::memcpy(&v, p, sizeof(T));
    p += sizeof(T);
    left -= sizeof(T);
    return true;
  }
  /// A count of items of `item_size` bytes that must fit in what is left.
  bool count(std::uint32_t& n, std::size_t item_size) { return get(n) && static_cast<std::size_t>(n) * item_size <= left; }
};

void put_level(Writer& w, const TemplateLevel& l) {
  w.put(l.scale);
  w.put(static_cast<std::uint32_t>(l.templates.size()));
  for (const Template& t : l.templates) {
    w.put(t.first);
    w.put(t.count);
    w.put(t.x0);
    w.put(t.y0);
    w.put(t.x1);
    w.put(t.y1);
  }
  w.put(static_cast<std::uint32_t>(l.features.size()));
  for (const Feature& f : l.features) {
    w.put(f.x);
    w.put(f.y);
    w.put(f.orientation);
  }
}

bool get_level(Reader& r, TemplateLevel& l) {
  std::uint32_t n = 0;
  if (!r.get(l.scale) || !r.count(n, 16)) return false;
  l.templates.resize(n);
  for (Template& t : l.templates)
    if (!r.get(t.first) || !r.get(t.count) || !r.get(t.x0) || !r.get(t.y0) || !r.get(t.x1) || !r.get(t.y1)) return false;
  if (!r.count(n, 5)) return false;
  l.features.resize(n);
  for (Feature& f : l.features)
    if (!r.get(f.x) || !r.get(f.y) || !r.get(f.orientation)) return false;
  return true;
}

void put_u32s(Writer& w, const std::vector<std::uint32_t>& v) {
  w.put(static_cast<std::uint32_t>(v.size()));
  for (std::uint32_t x : v) w.put(x);
}
bool get_u32s(Reader& r, std::vector<std::uint32_t>& v) {
  std::uint32_t n = 0;
  if (!r.count(n, 4)) return false;
  v.resize(n);
  for (std::uint32_t& x : v)
    if (!r.get(x)) return false;
  return true;
}

/// Every index in range: what a checksum cannot promise for a file written by another version.
bool consistent(const TemplateSet& s) {
  const std::size_t nv = static_cast<std::size_t>(s.n_elevation) * s.n_azimuth * s.n_inplane * s.n_distance;
  if (s.n_elevation < 1 || s.n_azimuth < 1 || s.n_inplane < 1 || s.n_distance < 1 || nv != s.views.size()) return false;
  if (s.fine.templates.size() != s.views.size() || s.coarse.templates.size() != s.coarse_views.size()) return false;
  if (s.child_offsets.size() != s.coarse_views.size() + 1 || s.child_offsets.front() != 0 ||
      s.child_offsets.back() != s.children.size())
    return false;
  for (std::size_t k = 0; k + 1 < s.child_offsets.size(); ++k)
    if (s.child_offsets[k] > s.child_offsets[k + 1]) return false;
  for (const std::uint32_t v : s.coarse_views)
    if (v >= s.views.size()) return false;
  for (const std::uint32_t v : s.children)
    if (v >= s.views.size()) return false;
  for (const TemplateLevel* l : {&s.fine, &s.coarse}) {
    for (const Template& t : l->templates) {
      if (static_cast<std::uint64_t>(t.first) + t.count > l->features.size() || t.count > 63) return false;
      for (std::uint32_t f = t.first; f < t.first + t.count; ++f) {
        const Feature& ft = l->features[f];
        if (ft.orientation >= kOrientations || ft.x < t.x0 || ft.x > t.x1 || ft.y < t.y0 || ft.y > t.y1) return false;
      }
    }
  }
  for (const TemplateView& v : s.views)
    if (!v.T_cam_obj.translation().allFinite() || !v.T_cam_obj.quaternion().coeffs().allFinite()) return false;
  return s.fx > 0 && s.fy > 0;
}

Unexpected file_error(const std::string& path, std::string msg) { return make_error(path, 0, 0, std::move(msg)); }

}  // namespace

std::uint64_t template_key(const model::Model& m, const geometry::PinholeCamera& cam, const DetectorParams& p) {
  Fnv f;
  f.add(TemplateSet::kFormatVersion);
  f.add(static_cast<std::uint64_t>(m.junctions().size()));
  for (const auto& j : m.junctions()) f.add(j.p);
  f.add(static_cast<std::uint64_t>(m.lines().size()));
  for (const auto& l : m.lines()) {
    f.add(l.a);
    f.add(l.b);
    f.add(l.face_left);
    f.add(l.face_right);
  }
  f.add(static_cast<std::uint64_t>(m.faces().size()));
  for (const auto& fc : m.faces()) {
    f.add(static_cast<std::uint64_t>(fc.loop.size()));
    for (const auto j : fc.loop) f.add(j);
    f.add(fc.normal);
  }
  f.add(static_cast<std::uint64_t>(m.arcs().size()));
  for (const auto& a : m.arcs()) {
    f.add(a.center);
    f.add(a.normal);
    f.add(a.x_axis);
    f.add(a.radius);
    f.add(a.start);
    f.add(a.end);
    f.add(a.face);
  }
  f.add(static_cast<std::uint64_t>(m.cylinders().size()));
  for (const auto& c : m.cylinders()) {
    f.add(c.p1);
    f.add(c.p2);
    f.add(c.radius);
  }
  f.add(cam.fx);
  f.add(cam.fy);
  const ViewRange v = resolve_view_range(p.views, model_extent(m).radius, cam.focal());
  for (const double x : {v.elevation_min_deg, v.elevation_max_deg, v.azimuth_min_deg, v.azimuth_max_deg, v.inplane_min_deg,
                         v.inplane_max_deg, v.distance_min_m, v.distance_max_m})
    f.add(x);
  const TemplateParams& t = p.templates;
  f.add(t.view_step_deg);
  f.add(t.inplane_step_deg);
  f.add(t.scale_step);
  f.add(t.coarse_stride);
  f.add(t.coarse_features);
  f.add(t.fine_features);
  f.add(t.crease_angle_deg);
  return f.h;
}

std::string default_cache_dir() {
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x != nullptr && x[0] != '\0') return (fs::path(x) / "v4r").string();
  if (const char* h = std::getenv("HOME"); h != nullptr && h[0] != '\0') return (fs::path(h) / ".cache" / "v4r").string();
  return ".v4r-cache";
}

std::string cache_file(const std::string& dir, std::uint64_t key) {
  return (fs::path(dir) / fmt::format("templates-{:016x}.v4rt", key)).string();
}

Expected<void> write_templates(const std::string& path, const TemplateSet& s, std::uint64_t key) {
  Writer w;
  for (int i = 0; i < 3; ++i) w.put(s.centre[i]);
  w.put(s.fx);
  w.put(s.fy);
  w.put(static_cast<std::int32_t>(s.n_elevation));
  w.put(static_cast<std::int32_t>(s.n_azimuth));
  w.put(static_cast<std::int32_t>(s.n_inplane));
  w.put(static_cast<std::int32_t>(s.n_distance));
  w.put(static_cast<std::uint8_t>(s.azimuth_wraps ? 1 : 0));
  w.put(static_cast<std::uint32_t>(s.views.size()));
  for (const TemplateView& v : s.views) {
    const Eigen::Quaterniond& q = v.T_cam_obj.quaternion();
    for (const double x : {q.w(), q.x(), q.y(), q.z()}) w.put(x);
    for (int i = 0; i < 3; ++i) w.put(v.T_cam_obj.translation()[i]);
    w.put(v.elevation);
    w.put(v.azimuth);
    w.put(v.inplane);
    w.put(v.distance);
  }
  put_level(w, s.fine);
  put_level(w, s.coarse);
  put_u32s(w, s.coarse_views);
  put_u32s(w, s.child_offsets);
  put_u32s(w, s.children);
  Fnv sum;
  sum.bytes(w.out.data(), w.out.size());
  Writer h;
  h.out.append(kMagic, sizeof(kMagic));
  h.put(TemplateSet::kFormatVersion);
  h.put(std::uint32_t{0});
  h.put(key);
  h.put(static_cast<std::uint64_t>(w.out.size()));
  h.put(sum.h);
  const std::string tmp = path + fmt::format(".tmp{}", static_cast<unsigned long>(::getpid()));
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) return file_error(tmp, "cannot create the template cache file");
    f.write(h.out.data(), static_cast<std::streamsize>(h.out.size()));
    f.write(w.out.data(), static_cast<std::streamsize>(w.out.size()));
    f.flush();
    if (!f) {
      std::error_code ec;
      fs::remove(tmp, ec);
      return file_error(tmp, "write failed (disk full?)");
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    return file_error(path, "cannot rename the new template cache file into place");
  }
  return {};
}

Expected<TemplateSet> read_templates(const std::string& path, std::uint64_t expected_key) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return file_error(path, "no cache file");
  const std::string data((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (data.size() < kHeaderSize) return file_error(path, fmt::format("corrupt: {} bytes, shorter than the header", data.size()));
  if (std::memcmp(data.data(), kMagic, sizeof(kMagic)) != 0) return file_error(path, "corrupt: not a v4r template file");
  Reader hr{data.data() + sizeof(kMagic), kHeaderSize - sizeof(kMagic)};
  std::uint32_t version = 0, reserved = 0;
  std::uint64_t key = 0, size = 0, checksum = 0;
  hr.get(version);
  hr.get(reserved);
  hr.get(key);
  hr.get(size);
  hr.get(checksum);
  if (version != TemplateSet::kFormatVersion)
    return file_error(path, fmt::format("stale: format version {}, this build reads {}", version, TemplateSet::kFormatVersion));
  if (key != expected_key) return file_error(path, "stale: built for another model, camera or view range");
  if (size != data.size() - kHeaderSize)
    return file_error(path, fmt::format("corrupt: payload of {} bytes, the header says {}", data.size() - kHeaderSize, size));
  Fnv sum;
  sum.bytes(data.data() + kHeaderSize, size);
  if (sum.h != checksum) return file_error(path, "corrupt: checksum mismatch");
  Reader r{data.data() + kHeaderSize, static_cast<std::size_t>(size)};
  TemplateSet s;
  std::int32_t ne = 0, na = 0, ni = 0, nd = 0;
  std::uint8_t wraps = 0;
  std::uint32_t nviews = 0;
  bool ok = r.get(s.centre[0]) && r.get(s.centre[1]) && r.get(s.centre[2]) && r.get(s.fx) && r.get(s.fy) && r.get(ne) &&
            r.get(na) && r.get(ni) && r.get(nd) && r.get(wraps) && r.count(nviews, 64);
  if (ok) {
    s.n_elevation = ne;
    s.n_azimuth = na;
    s.n_inplane = ni;
    s.n_distance = nd;
    s.azimuth_wraps = wraps != 0;
    s.views.resize(nviews);
    for (TemplateView& v : s.views) {
      double q[4], t[3];
      for (double& x : q) ok = ok && r.get(x);
      for (double& x : t) ok = ok && r.get(x);
      ok = ok && r.get(v.elevation) && r.get(v.azimuth) && r.get(v.inplane) && r.get(v.distance);
      if (!ok) break;
      v.T_cam_obj = geometry::SE3(Eigen::Quaterniond(q[0], q[1], q[2], q[3]), Eigen::Vector3d(t[0], t[1], t[2]));
    }
  }
  ok = ok && get_level(r, s.fine) && get_level(r, s.coarse) && get_u32s(r, s.coarse_views) && get_u32s(r, s.child_offsets) &&
       get_u32s(r, s.children) && r.left == 0;
  if (!ok || !consistent(s)) return file_error(path, "corrupt: the content is inconsistent");
  return s;
}

Expected<std::shared_ptr<const TemplateSet>> load_or_build(const model::Model& model, const geometry::PinholeCamera& cam,
                                                           const DetectorParams& p, const std::string& dir_in,
                                                           CacheReport* report, const BuildProgress& progress) {
  CacheReport local;
  CacheReport& rep = report ? *report : local;
  rep = CacheReport{};
  const std::string dir = dir_in.empty() ? default_cache_dir() : dir_in;
  const std::uint64_t key = template_key(model, cam, p);
  rep.path = cache_file(dir, key);
  auto cached = read_templates(rep.path, key);
  if (cached) return std::shared_ptr<const TemplateSet>(std::make_shared<TemplateSet>(std::move(*cached)));
  rep.built = true;
  rep.reason = cached.error().message;
  auto built = build_templates(model, cam, p, progress);
  if (!built) return built.error();
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) {
    rep.write_error = fmt::format("{}: cannot create the cache folder: {}", dir, ec.message());
  } else if (auto w = write_templates(rep.path, *built, key); !w) {
    rep.write_error = w.error().to_string();
  } else {
    rep.written = true;
  }
  return std::shared_ptr<const TemplateSet>(std::make_shared<TemplateSet>(std::move(*built)));
}

}  // namespace v4r::detection
