// v4r - robust model-based object tracking. MIT licence.
#include "v4r/model/mesh_writer.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>

#include <Eigen/Geometry>
#include <fmt/format.h>

namespace v4r::model {

namespace {

static_assert(std::endian::native == std::endian::little, "the binary STL writer assumes a little-endian host");

/// Twice the signed area of the 2-D triangle (a, b, c): > 0 when counter-clockwise.
double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const Eigen::Vector2d u = b - a, v = c - a;
  return u.x() * v.y() - u.y() * v.x();
}

bool inside_triangle(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                     const Eigen::Vector2d& c) {
  return cross2(a, b, p) >= 0.0 && cross2(b, c, p) >= 0.0 && cross2(c, a, p) >= 0.0;
}

/// Ear clipping of a planar loop (CCW about `normal`), trying the ear at the loop's second vertex
/// first so that a convex polygon yields the fan from loop[0]. Falls back to a fan when no ear
/// is found (degenerate input).
void triangulate_loop(const std::vector<Index>& loop, const Eigen::Vector3d& normal,
                      const std::vector<Eigen::Vector3d>& pts, std::vector<std::array<Index, 3>>& out) {
  if (loop.size() < 3) return;
  const Eigen::Vector3d u = normal.unitOrthogonal(), v = normal.cross(u);
  std::vector<Index> rest = loop;
  std::vector<Eigen::Vector2d> q;
  q.reserve(loop.size());
  for (Index j : loop) q.emplace_back(pts[j].dot(u), pts[j].dot(v));
  std::vector<std::size_t> idx(loop.size());
  for (std::size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  double scale2 = 0.0;
  for (const auto& p : q) scale2 = std::max(scale2, (p - q[0]).squaredNorm());
  const double eps = 1e-12 * scale2;
  while (idx.size() > 3) {
    const std::size_t n = idx.size();
    bool clipped = false;
    for (std::size_t k = 0; k < n && !clipped; ++k) {
      const std::size_t i = (k + 1) % n;
      const std::size_t ip = (i + n - 1) % n, in = (i + 1) % n;
      const Eigen::Vector2d &a = q[idx[ip]], &b = q[idx[i]], &c = q[idx[in]];
      if (cross2(a, b, c) <= eps) continue;  // reflex or flat corner
      bool empty = true;
      for (std::size_t m = 0; m < n && empty; ++m) {
        if (m == ip || m == i || m == in) continue;
        const Eigen::Vector2d& p = q[idx[m]];
        if (p == a || p == b || p == c) continue;
        if (inside_triangle(p, a, b, c)) empty = false;
      }
      if (!empty) continue;
      out.push_back({loop[idx[ip]], loop[idx[i]], loop[idx[in]]});
      idx.erase(idx.begin() + static_cast<std::ptrdiff_t>(i));
      clipped = true;
    }
    if (!clipped) {  // degenerate polygon: fan over what is left
      for (std::size_t k = 1; k + 1 < idx.size(); ++k) out.push_back({loop[idx[0]], loop[idx[k]], loop[idx[k + 1]]});
      return;
    }
  }
  out.push_back({loop[idx[0]], loop[idx[1]], loop[idx[2]]});
}

MeshFormat format_of(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".obj") return MeshFormat::kObj;
  if (ext == ".stl") return MeshFormat::kStlBinary;
  if (ext == ".ply") return MeshFormat::kPlyAscii;
  return MeshFormat::kAuto;
}

Unexpected file_error(const std::string& path, std::string message) {
  return Unexpected{Error{std::move(message), path, 0, 0, {}}};
}

void put_f32(std::string& buf, double x) {
  const auto f = static_cast<float>(x);
  char b[4];
  std::memcpy(b, &f, 4);
  buf.append(b, 4);
}

}  // namespace

TriangleMesh triangulate(const Model& model, int cylinder_segments, bool cylinder_caps) {
  TriangleMesh mesh;
  mesh.vertices.reserve(model.junctions().size());
  for (const Junction& j : model.junctions()) mesh.vertices.push_back(j.p);
  for (const Face& f : model.faces()) triangulate_loop(f.loop, f.normal, mesh.vertices, mesh.triangles);

  const int n = std::max(3, cylinder_segments);
  for (const Cylinder& c : model.cylinders()) {
    const Eigen::Vector3d axis = c.p2 - c.p1;
    if (axis.norm() <= 0.0 || !(c.radius > 0.0)) continue;
    const Eigen::Vector3d nz = axis.normalized();
    const Eigen::Vector3d nx = nz.unitOrthogonal(), ny = nz.cross(nx);
    const auto first = static_cast<Index>(mesh.vertices.size());
    for (int k = 0; k < n; ++k) {  // bottom rim at even, top rim at odd offsets
      const double th = 2.0 * std::numbers::pi * k / n;
      const Eigen::Vector3d radial = c.radius * (std::cos(th) * nx + std::sin(th) * ny);
      mesh.vertices.push_back(c.p1 + radial);
      mesh.vertices.push_back(c.p2 + radial);
    }
    auto bottom = [&](int k) { return static_cast<Index>(first + 2 * (k % n)); };
    auto top = [&](int k) { return static_cast<Index>(first + 2 * (k % n) + 1); };
    for (int k = 0; k < n; ++k) {  // (b_k, b_k+1, t_k+1, t_k) runs CCW seen from outside
      mesh.triangles.push_back({bottom(k), bottom(k + 1), top(k + 1)});
      mesh.triangles.push_back({bottom(k), top(k + 1), top(k)});
    }
    if (cylinder_caps) {
      const auto c1 = static_cast<Index>(mesh.vertices.size());
      mesh.vertices.push_back(c.p1);
      const auto c2 = static_cast<Index>(mesh.vertices.size());
      mesh.vertices.push_back(c.p2);
      for (int k = 0; k < n; ++k) {
        mesh.triangles.push_back({c1, bottom(k + 1), bottom(k)});  // normal -axis
        mesh.triangles.push_back({c2, top(k), top(k + 1)});        // normal +axis
      }
    }
  }
  return mesh;
}

Expected<void> write_mesh(const TriangleMesh& mesh, const std::string& path, MeshFormat format) {
  if (format == MeshFormat::kAuto) format = format_of(path);
  if (format == MeshFormat::kAuto)
    return file_error(path, "unknown mesh file extension (expected .obj, .stl or .ply)");
  for (const auto& t : mesh.triangles) {
    for (Index i : t) {
      if (i >= mesh.vertices.size()) return file_error(path, fmt::format("triangle refers to vertex {} of {}", i, mesh.vertices.size()));
    }
  }
  std::string buf;
  switch (format) {
    case MeshFormat::kObj: {
      buf += "# v4r mesh export: triangles counter-clockwise seen from outside\n";
      for (const auto& p : mesh.vertices) buf += fmt::format("v {} {} {}\n", p.x(), p.y(), p.z());
      for (const auto& t : mesh.triangles) buf += fmt::format("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
      break;
    }
    case MeshFormat::kStlBinary: {
      // The 80-byte header must not start with "solid" (readers would take the file for ASCII).
      std::string header = "v4r binary STL export";
      header.resize(80, ' ');
      buf += header;
      const auto count = static_cast<std::uint32_t>(mesh.triangles.size());
      char b[4];
      std::memcpy(b, &count, 4);
      buf.append(b, 4);
      buf.reserve(buf.size() + 50 * mesh.triangles.size());
      for (const auto& t : mesh.triangles) {
        const Eigen::Vector3d &a = mesh.vertices[t[0]], &bb = mesh.vertices[t[1]], &c = mesh.vertices[t[2]];
        Eigen::Vector3d nrm = (bb - a).cross(c - a);
        if (nrm.norm() > 0.0) nrm.normalize();
        for (int k = 0; k < 3; ++k) put_f32(buf, nrm[k]);
        for (const Eigen::Vector3d* p : {&a, &bb, &c}) {
          for (int k = 0; k < 3; ++k) put_f32(buf, (*p)[k]);
        }
        buf.append(2, '\0');  // attribute byte count
      }
      break;
    }
    case MeshFormat::kPlyAscii: {
      buf += fmt::format(
          "ply\nformat ascii 1.0\ncomment v4r mesh export\nelement vertex {}\nproperty double x\nproperty double y\n"
          "property double z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
          mesh.vertices.size(), mesh.triangles.size());
      for (const auto& p : mesh.vertices) buf += fmt::format("{} {} {}\n", p.x(), p.y(), p.z());
      for (const auto& t : mesh.triangles) buf += fmt::format("3 {} {} {}\n", t[0], t[1], t[2]);
      break;
    }
    case MeshFormat::kAuto:
      break;
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return file_error(path, "cannot open the file for writing");
  out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
  out.close();
  if (!out) return file_error(path, "writing the file failed");
  return {};
}

Expected<void> write_mesh(const Model& model, const std::string& path, const MeshWriteOptions& opt) {
  TriangleMesh mesh = triangulate(model, opt.cylinder_segments, opt.cylinder_caps);
  for (auto& p : mesh.vertices) p = opt.scale * (opt.T_file_obj * p);
  return write_mesh(mesh, path, opt.format);
}

}  // namespace v4r::model
