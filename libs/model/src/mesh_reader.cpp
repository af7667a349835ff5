// v4r - robust model-based object tracking. MIT licence.
//
// Mesh import: assimp reads the file; the rest (weld, orientation, sharp edges, collinear merge,
// circle recovery, coplanar face merge) is done here on a plain indexed triangle list.
#include "v4r/model/mesh_reader.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <numbers>
#include <optional>
#include <unordered_map>
#include <utility>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <fmt/format.h>

namespace v4r::model {

namespace {

using Clock = std::chrono::steady_clock;
using Eigen::Vector3d;

constexpr double kTwoPi = 2.0 * std::numbers::pi;
/// Smallest turn (radians) between consecutive pieces of a circle: below it they count as straight.
constexpr double kMinArcTurn = 1e-5;
/// Relative precision of the coordinates in a mesh file (most hold single-precision floats).
constexpr double kFileFloatEps = 6e-8;
/// Planarity tolerance (metres) handed to ModelBuilder::add_face for merged faces.
constexpr double kFacePlanarity = 1e-4;
/// A circle whose radius exceeds this multiple of its points' extent is taken for a straight run.
constexpr double kMaxRadiusOverExtent = 1e4;
/// Relative deviation allowed between a chain's turn at a vertex and the turn of the fitted circle.
constexpr double kTurnTolerance = 0.5;
/// Triangles whose normal is within this angle (radians) of a circle's normal lie in its plane.
constexpr double kArcFaceAngle = 0.05;
/// Triangles with twice their area below this times their longest edge squared are dropped.
constexpr double kMinTriangleSine = 1e-12;

Unexpected file_error(const std::string& file, std::string message) {
  return Unexpected{Error{std::move(message), file, 0, 0, {}}};
}

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// ------------------------------------------------------------------------------------------
// Weld: greedy clustering on a hash grid whose cell is the tolerance; a vertex joins the first
// representative within the tolerance found in its 27 neighbouring cells.

std::vector<Index> weld(const std::vector<Vector3d>& pts, double tol, std::vector<Vector3d>& out) {
  double max_abs = 0.0;
  for (const Vector3d& p : pts) max_abs = std::max(max_abs, p.cwiseAbs().maxCoeff());
  const double cell = std::max({tol, max_abs * 1e-12, 1e-300});
  auto cell_of = [&](const Vector3d& p) {
    return Eigen::Array<std::int64_t, 3, 1>(static_cast<std::int64_t>(std::floor(p.x() / cell)),
                                            static_cast<std::int64_t>(std::floor(p.y() / cell)),
                                            static_cast<std::int64_t>(std::floor(p.z() / cell)));
  };
  auto key_of = [](std::int64_t x, std::int64_t y, std::int64_t z) {
    return static_cast<std::uint64_t>(x) * 0x9E3779B97F4A7C15ull ^ static_cast<std::uint64_t>(y) * 0xC2B2AE3D27D4EB4Full ^
           static_cast<std::uint64_t>(z) * 0x165667B19E3779F9ull;
  };
  std::unordered_map<std::uint64_t, Index> head;  // cell key -> first representative in it
  head.reserve(pts.size());
  std::vector<Index> next_rep;  // intrusive list of representatives sharing a key
  std::vector<Index> map(pts.size());
  const double tol2 = tol * tol;
  out.clear();
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const Vector3d& p = pts[i];
    const auto c = cell_of(p);
    Index found = kNone;
    for (int dx = -1; dx <= 1 && found == kNone; ++dx) {
      for (int dy = -1; dy <= 1 && found == kNone; ++dy) {
        for (int dz = -1; dz <= 1 && found == kNone; ++dz) {
          const auto it = head.find(key_of(c.x() + dx, c.y() + dy, c.z() + dz));
          for (Index r = it == head.end() ? kNone : it->second; r != kNone; r = next_rep[r]) {
            if ((out[r] - p).squaredNorm() <= tol2) {
              found = r;
              break;
            }
          }
        }
      }
    }
    if (found == kNone) {
      found = static_cast<Index>(out.size());
      out.push_back(p);
      const std::uint64_t k = key_of(c.x(), c.y(), c.z());
      const auto it = head.find(k);
      next_rep.push_back(it == head.end() ? kNone : it->second);
      head[k] = found;
    }
    map[i] = found;
  }
  return map;
}

// ------------------------------------------------------------------------------------------
// Edge table: the three directed edges of every triangle, grouped by undirected edge.

struct HalfEdge {
  std::uint64_t key;  // (min vertex << 32) | max vertex
  Index tri;
  std::uint8_t slot;  // edge from tri[slot] to tri[(slot + 1) % 3]
};

struct EdgeTable {
  std::vector<HalfEdge> half;      // sorted by key
  std::vector<std::size_t> first;  // group g spans half[first[g] .. first[g + 1])
  std::vector<Index> group_of;     // per triangle slot (3 * tri + slot) -> group
  [[nodiscard]] std::size_t groups() const { return first.size() - 1; }
  [[nodiscard]] std::size_t size(std::size_t g) const { return first[g + 1] - first[g]; }
};

EdgeTable make_edges(const std::vector<std::array<Index, 3>>& tris) {
  EdgeTable e;
  e.half.reserve(3 * tris.size());
  for (std::size_t t = 0; t < tris.size(); ++t) {
    for (std::uint8_t k = 0; k < 3; ++k) {
      const Index a = tris[t][k], b = tris[t][(k + 1) % 3];
      const std::uint64_t key = (static_cast<std::uint64_t>(std::min(a, b)) << 32) | std::max(a, b);
      e.half.push_back({key, static_cast<Index>(t), k});
    }
  }
  std::sort(e.half.begin(), e.half.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return x.key != y.key ? x.key < y.key : (x.tri != y.tri ? x.tri < y.tri : x.slot < y.slot);
  });
  e.group_of.assign(3 * tris.size(), 0);
  for (std::size_t i = 0; i < e.half.size(); ++i) {
    if (i == 0 || e.half[i].key != e.half[i - 1].key) e.first.push_back(i);
    e.group_of[3 * e.half[i].tri + e.half[i].slot] = static_cast<Index>(e.first.size() - 1);
  }
  e.first.push_back(e.half.size());
  return e;
}

/// The directed edge (from, to) of a half edge.
std::pair<Index, Index> directed(const std::vector<std::array<Index, 3>>& tris, const HalfEdge& h) {
  return {tris[h.tri][h.slot], tris[h.tri][(h.slot + 1) % 3]};
}

// ------------------------------------------------------------------------------------------
// Orientation: propagate a consistent winding over manifold edges; closed parts are turned
// outward (positive volume), open parts keep the winding most of their triangles had.

std::size_t fix_orientation(const std::vector<Vector3d>& P, std::vector<std::array<Index, 3>>& tris) {
  const EdgeTable e = make_edges(tris);
  std::vector<std::int8_t> flip(tris.size(), -1);
  std::vector<Index> comp, queue;
  std::size_t flipped = 0;
  for (std::size_t seed = 0; seed < tris.size(); ++seed) {
    if (flip[seed] >= 0) continue;
    comp.clear();
    queue.assign(1, static_cast<Index>(seed));
    flip[seed] = 0;
    bool closed = true;
    while (!queue.empty()) {
      const Index t = queue.back();
      queue.pop_back();
      comp.push_back(t);
      for (int k = 0; k < 3; ++k) {
        const Index g = e.group_of[3 * t + k];
        if (e.size(g) != 2) {
          closed = false;
          continue;
        }
        const HalfEdge& h0 = e.half[e.first[g]];
        const HalfEdge& h1 = e.half[e.first[g] + 1];
        const HalfEdge& mine = h0.tri == t ? h0 : h1;
        const HalfEdge& other = h0.tri == t ? h1 : h0;
        if (other.tri == t) continue;
        const bool same_dir = directed(tris, mine).first == directed(tris, other).first;
        const std::int8_t want = static_cast<std::int8_t>(flip[t] ^ (same_dir ? 1 : 0));
        if (flip[other.tri] < 0) {
          flip[other.tri] = want;
          queue.push_back(other.tri);
        }
      }
    }
    bool invert = false;
    if (closed) {
      double vol = 0.0;
      for (Index t : comp) {
        const Vector3d &a = P[tris[t][0]], &b = P[tris[t][1]], &c = P[tris[t][2]];
        const double v = a.dot(b.cross(c));
        vol += flip[t] ? -v : v;
      }
      invert = vol < 0.0;
    } else {
      std::size_t n_flip = 0;
      for (Index t : comp) n_flip += flip[t] ? 1 : 0;
      invert = 2 * n_flip > comp.size();
    }
    for (Index t : comp) {
      if ((flip[t] != 0) != invert) {
        std::swap(tris[t][1], tris[t][2]);
        ++flipped;
      }
    }
  }
  return flipped;
}

// ------------------------------------------------------------------------------------------
// Circles.

struct CircleFit {
  Vector3d centre, normal;
  double radius = 0.0;
};

/// Plane fit (least squares) and algebraic circle fit in that plane; accepted when every point
/// lies within tol * radius of the plane and of the circle.
std::optional<CircleFit> fit_circle(const std::vector<Vector3d>& Q, std::size_t i0, std::size_t i1, double tol) {
  const std::size_t n = i1 - i0;
  if (n < 3) return std::nullopt;
  Vector3d c = Vector3d::Zero();
  for (std::size_t i = i0; i < i1; ++i) c += Q[i];
  c /= static_cast<double>(n);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  Vector3d lo = Q[i0], hi = Q[i0];
  for (std::size_t i = i0; i < i1; ++i) {
    const Vector3d d = Q[i] - c;
    cov += d * d.transpose();
    lo = lo.cwiseMin(Q[i]);
    hi = hi.cwiseMax(Q[i]);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  const Vector3d nrm = es.eigenvectors().col(0).normalized();
  const Vector3d u = nrm.unitOrthogonal(), v = nrm.cross(u);
  Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
  Vector3d Atb = Vector3d::Zero();
  for (std::size_t i = i0; i < i1; ++i) {
    const Vector3d d = Q[i] - c;
    const Vector3d row(d.dot(u), d.dot(v), 1.0);
    const double rhs = -(row.x() * row.x() + row.y() * row.y());
    AtA += row * row.transpose();
    Atb += row * rhs;
  }
  const Vector3d sol = AtA.ldlt().solve(Atb);
  if (!sol.allFinite()) return std::nullopt;
  const double cx = -0.5 * sol.x(), cy = -0.5 * sol.y();
  const double r2 = cx * cx + cy * cy - sol.z();
  if (!(r2 > 0.0)) return std::nullopt;
  CircleFit f;
  f.radius = std::sqrt(r2);
  f.centre = c + cx * u + cy * v;
  f.normal = nrm;
  if (f.radius > kMaxRadiusOverExtent * (hi - lo).norm()) return std::nullopt;
  for (std::size_t i = i0; i < i1; ++i) {
    const Vector3d d = Q[i] - f.centre;
    const double h = d.dot(nrm);
    const double rho = (d - h * nrm).norm();
    if (std::abs(h) > tol * f.radius || std::abs(rho - f.radius) > tol * f.radius) return std::nullopt;
  }
  return f;
}

/// Signed turn (radians) about `n` from direction a to direction b.
double turn(const Vector3d& a, const Vector3d& b, const Vector3d& n) {
  return std::atan2(a.cross(b).dot(n), a.dot(b));
}

/// Whether the turn between two consecutive chords (lengths c1, c2) matches a circle of radius
/// r: a polygon inscribed in a circle turns by asin(c1 / 2r) + asin(c2 / 2r) at each vertex.
/// This tells a circle through the corners of small arcs (same radius tolerance, wrong turns)
/// from the true one.
bool turn_fits(double t, double c1, double c2, double r) {
  const double expected = std::asin(std::min(1.0, 0.5 * c1 / r)) + std::asin(std::min(1.0, 0.5 * c2 / r));
  return std::abs(std::abs(t) - expected) <= kTurnTolerance * expected;
}

/// A run of pieces [begin, end) of a chain, and the circle it lies on, if any.
struct Segment {
  std::size_t begin = 0, end = 0;
  std::optional<CircleFit> circle;
};

/// Finds arcs in the open vertex sequence Q[0..k] (piece i runs from Q[i] to Q[i+1]) greedily:
/// from each start, the longest run of >= min_pieces pieces turning one way whose vertices fit
/// one circle. Returns the arcs, in order.
std::vector<Segment> find_arcs(const std::vector<Vector3d>& Q, const MeshImportOptions& opt) {
  std::vector<Segment> arcs;
  const std::size_t k = Q.size() - 1;
  const auto m = static_cast<std::size_t>(std::max(3, opt.min_circle_segments));
  auto dir = [&](std::size_t i) -> Vector3d { return (Q[i + 1] - Q[i]).normalized(); };
  // turn at vertex Q[i] between piece i-1 and piece i
  auto turn_at = [&](std::size_t i, const Vector3d& n) { return turn(dir(i - 1), dir(i), n); };
  auto chord = [&](std::size_t i) { return (Q[i + 1] - Q[i]).norm(); };
  std::size_t i = 0;
  while (i + m <= k) {
    // A straight vertex inside the window rules out every window around it: restart there.
    std::size_t straight = 0;
    for (std::size_t v = i + 1; v < i + m && straight == 0; ++v) {
      if (dir(v - 1).cross(dir(v)).norm() < kMinArcTurn && dir(v - 1).dot(dir(v)) > 0.0) straight = v;
    }
    if (straight != 0) {
      i = straight;
      continue;
    }
    std::optional<CircleFit> fit = fit_circle(Q, i, i + m + 1, opt.circle_tolerance);
    double sign = 0.0, total = 0.0;
    bool ok = fit.has_value();
    for (std::size_t v = i + 1; ok && v < i + m; ++v) {
      const double t = turn_at(v, fit->normal);
      if (std::abs(t) < kMinArcTurn || (sign != 0.0 && t * sign <= 0.0)) ok = false;
      if (!turn_fits(t, chord(v - 1), chord(v), fit->radius)) ok = false;
      sign = t > 0.0 ? 1.0 : -1.0;
      total += std::abs(t);
    }
    if (!ok) {
      ++i;
      continue;
    }
    // Grow: check each new vertex against the current circle, refit when the run grew by half.
    std::size_t j = i + m;  // pieces [i, j)
    std::size_t fitted = j;
    CircleFit good = *fit;
    while (j < k) {
      const double t = turn_at(j, fit->normal);
      if (std::abs(t) < kMinArcTurn || t * sign <= 0.0 || total + std::abs(t) > kTwoPi + 1e-9) break;
      if (!turn_fits(t, chord(j - 1), chord(j), fit->radius)) break;
      const Vector3d d = Q[j + 1] - fit->centre;
      const double h = d.dot(fit->normal);
      const double rho = (d - h * fit->normal).norm();
      if (std::abs(h) > opt.circle_tolerance * fit->radius ||
          std::abs(rho - fit->radius) > opt.circle_tolerance * fit->radius)
        break;
      total += std::abs(t);
      ++j;
      if (2 * (j - i) >= 3 * (fitted - i)) {
        auto refit = fit_circle(Q, i, j + 1, opt.circle_tolerance);
        if (!refit) {
          j = fitted;
          break;
        }
        if (refit->normal.dot(fit->normal) < 0.0) refit->normal = -refit->normal;  // keep the turn sign
        fit = refit;
        good = *refit;
        fitted = j;
      }
    }
    if (j != fitted) {
      const auto refit = fit_circle(Q, i, j + 1, opt.circle_tolerance);
      if (refit) {
        good = *refit;
      } else {
        j = fitted;
      }
    }
    arcs.push_back({i, j, good});
    i = j;
  }
  return arcs;
}

/// Whole closed loop Q[0..k] (Q[k] == Q[0]) on one circle, turning one way once around.
std::optional<CircleFit> full_circle(const std::vector<Vector3d>& Q, const MeshImportOptions& opt) {
  const std::size_t k = Q.size() - 1;
  if (k < static_cast<std::size_t>(std::max(3, opt.min_circle_segments))) return std::nullopt;
  auto fit = fit_circle(Q, 0, k, opt.circle_tolerance);
  if (!fit) return std::nullopt;
  double total = 0.0, sign = 0.0;
  for (std::size_t i = 0; i < k; ++i) {
    const Vector3d a = (Q[i == 0 ? k : i] - Q[i == 0 ? k - 1 : i - 1]).normalized();
    const Vector3d b = (Q[i + 1] - Q[i]).normalized();
    const double t = turn(a, b, fit->normal);
    if (std::abs(t) < kMinArcTurn || (sign != 0.0 && t * sign <= 0.0)) return std::nullopt;
    if (!turn_fits(t, (Q[i == 0 ? k : i] - Q[i == 0 ? k - 1 : i - 1]).norm(), (Q[i + 1] - Q[i]).norm(), fit->radius))
      return std::nullopt;
    sign = t > 0.0 ? 1.0 : -1.0;
    total += t;
  }
  if (std::abs(std::abs(total) - kTwoPi) > 1e-3) return std::nullopt;
  return fit;
}

/// Splits pieces [p0, p1) of Q into straight lines: a piece joins the current line while it is
/// within collinear_angle of both the previous piece and the line so far.
void split_lines(const std::vector<Vector3d>& Q, std::size_t p0, std::size_t p1, double collinear_angle,
                 std::vector<Segment>& out) {
  const double cos_max = std::cos(collinear_angle);
  std::size_t s = p0;
  while (s < p1) {
    std::size_t e = s + 1;
    while (e < p1) {
      const Vector3d d_next = (Q[e + 1] - Q[e]).normalized();
      const Vector3d d_prev = (Q[e] - Q[e - 1]).normalized();
      const Vector3d d_line = (Q[e] - Q[s]).normalized();
      if (d_next.dot(d_prev) < cos_max || d_next.dot(d_line) < cos_max) break;
      ++e;
    }
    out.push_back({s, e, std::nullopt});
    s = e;
  }
}

/// Arcs (if enabled) and straight lines covering all pieces of the open sequence Q, in order.
std::vector<Segment> segment_open(const std::vector<Vector3d>& Q, const MeshImportOptions& opt) {
  std::vector<Segment> arcs;
  if (opt.detect_circles) arcs = find_arcs(Q, opt);
  std::vector<Segment> out;
  std::size_t at = 0;
  for (const Segment& a : arcs) {
    split_lines(Q, at, a.begin, opt.collinear_angle, out);
    out.push_back(a);
    at = a.end;
  }
  split_lines(Q, at, Q.size() - 1, opt.collinear_angle, out);
  return out;
}

// ------------------------------------------------------------------------------------------
// The mesh after cleaning, with its edge table, normals and sharp edges.

struct Mesh {
  std::vector<Vector3d> P;                   // welded vertices (object frame, metres)
  std::vector<std::array<Index, 3>> tris;    // consistent, outward winding
  EdgeTable E;
  std::vector<Vector3d> N;                   // unit triangle normals
  std::vector<char> sharp;                   // per edge group
  double plane_tol = 0.0;                    // metres: "on a plane / line" tolerance

  /// The other triangle across a manifold edge group g, seen from triangle t.
  [[nodiscard]] Index across(Index g, Index t) const {
    const HalfEdge& h0 = E.half[E.first[g]];
    const HalfEdge& h1 = E.half[E.first[g] + 1];
    return h0.tri == t ? h1.tri : h0.tri;
  }
  /// Whether the two triangles of a manifold edge group run along it in opposite directions.
  [[nodiscard]] bool consistent(Index g) const {
    return directed(tris, E.half[E.first[g]]).first != directed(tris, E.half[E.first[g] + 1]).first;
  }
};

/// Weld, drop degenerate and duplicate triangles, fix the winding, classify edges.
Expected<Mesh> prepare(const TriangleMesh& in, const std::string& source, const MeshImportOptions& opt,
                       MeshImportStats& st) {
  Mesh m;
  const std::vector<Index> vmap = weld(in.vertices, opt.weld_tolerance, m.P);
  st.welded_vertices = m.P.size();
  auto& P = m.P;
  auto& tris = m.tris;
  tris.reserve(in.triangles.size());
  for (const auto& t : in.triangles) {
    const std::array<Index, 3> w{vmap[t[0]], vmap[t[1]], vmap[t[2]]};
    if (w[0] == w[1] || w[1] == w[2] || w[0] == w[2]) continue;
    const Vector3d e1 = P[w[1]] - P[w[0]], e2 = P[w[2]] - P[w[0]], e3 = P[w[2]] - P[w[1]];
    const double longest2 = std::max({e1.squaredNorm(), e2.squaredNorm(), e3.squaredNorm()});
    if (e1.cross(e2).norm() <= kMinTriangleSine * longest2) continue;  // collinear corners
    tris.push_back(w);
  }
  // Duplicates (the same three vertices in any order, e.g. a double-sided sheet): keep the first.
  std::vector<std::pair<std::array<Index, 3>, Index>> sorted;
  sorted.reserve(tris.size());
  for (std::size_t t = 0; t < tris.size(); ++t) {
    std::array<Index, 3> k = tris[t];
    std::sort(k.begin(), k.end());
    sorted.emplace_back(k, static_cast<Index>(t));
  }
  std::sort(sorted.begin(), sorted.end());
  std::vector<char> keep(tris.size(), 1);
  for (std::size_t i = 1; i < sorted.size(); ++i) {
    if (sorted[i].first == sorted[i - 1].first) keep[sorted[i].second] = 0;
  }
  std::size_t n_kept = 0;
  for (std::size_t t = 0; t < tris.size(); ++t) {
    if (keep[t]) tris[n_kept++] = tris[t];
  }
  tris.resize(n_kept);
  if (tris.empty()) return file_error(source, "the mesh contains only degenerate triangles");
  st.triangles = tris.size();

  if (opt.fix_orientation) st.flipped_triangles = fix_orientation(P, tris);
  m.E = make_edges(tris);
  m.N.resize(tris.size());
  for (std::size_t t = 0; t < tris.size(); ++t)
    m.N[t] = (P[tris[t][1]] - P[tris[t][0]]).cross(P[tris[t][2]] - P[tris[t][0]]).normalized();

  // Sharp: open boundary, non-manifold, or a dihedral angle above sharp_angle.
  const std::size_t G = m.E.groups();
  m.sharp.assign(G, 0);
  const double cos_sharp = std::cos(opt.sharp_angle);
  for (std::size_t g = 0; g < G; ++g) {
    const std::size_t n = m.E.size(g);
    if (n != 2) {
      m.sharp[g] = 1;
      if (n == 1) ++st.boundary_pieces;
    } else {
      const HalfEdge& h0 = m.E.half[m.E.first[g]];
      const HalfEdge& h1 = m.E.half[m.E.first[g] + 1];
      const double c = (m.consistent(static_cast<Index>(g)) ? 1.0 : -1.0) * m.N[h0.tri].dot(m.N[h1.tri]);
      m.sharp[g] = c < cos_sharp ? 1 : 0;
    }
    st.sharp_pieces += m.sharp[g] ? 1 : 0;
  }
  // A point is on a plane within the weld tolerance, or the rounding of single-precision
  // coordinates if that is larger.
  double max_abs = 0.0;
  for (const Vector3d& p : P) max_abs = std::max(max_abs, p.cwiseAbs().maxCoeff());
  m.plane_tol = std::max({opt.weld_tolerance, 8.0 * kFileFloatEps * max_abs, 1e-12});
  return m;
}

// ------------------------------------------------------------------------------------------
// Faces: coplanar regions grown over smooth, consistently wound manifold edges.

struct Regions {
  std::vector<Index> of_tri;                // triangle -> region
  std::vector<std::vector<Index>> tris;     // region -> triangles
  std::vector<std::vector<Index>> loop;     // region -> boundary loop (CCW), empty if not simple
};

std::vector<Index> region_loop(const Mesh& m, const Regions& R, Index r);

Regions grow_regions(const Mesh& m, const MeshImportOptions& opt) {
  Regions R;
  R.of_tri.assign(m.tris.size(), kNone);
  const double cos_coplanar = std::cos(opt.coplanar_angle);
  std::vector<Index> queue;
  for (std::size_t seed = 0; seed < m.tris.size(); ++seed) {
    if (R.of_tri[seed] != kNone) continue;
    const auto r = static_cast<Index>(R.tris.size());
    R.tris.emplace_back();
    R.of_tri[seed] = r;
    queue.assign(1, static_cast<Index>(seed));
    const Vector3d n0 = m.N[seed];
    const Vector3d p0 = m.P[m.tris[seed][0]];
    while (!queue.empty()) {
      const Index t = queue.back();
      queue.pop_back();
      R.tris[r].push_back(t);
      if (!opt.merge_coplanar) continue;
      for (int k = 0; k < 3; ++k) {
        const Index g = m.E.group_of[3 * t + k];
        if (m.E.size(g) != 2 || m.sharp[g] || !m.consistent(g)) continue;
        const Index u = m.across(g, t);
        if (R.of_tri[u] != kNone || m.N[u].dot(n0) < cos_coplanar) continue;
        bool on_plane = true;
        for (Index v : m.tris[u]) on_plane = on_plane && std::abs(n0.dot(m.P[v] - p0)) <= m.plane_tol;
        if (!on_plane) continue;
        R.of_tri[u] = r;
        queue.push_back(u);
      }
    }
  }
  R.loop.resize(R.tris.size());
  for (std::size_t r = 0; r < R.tris.size(); ++r) R.loop[r] = region_loop(m, R, static_cast<Index>(r));
  return R;
}

/// The boundary of region r as one loop, with vertices on straight stretches dropped; empty when
/// the boundary is not one simple loop (a hole, or a vertex visited twice).
std::vector<Index> region_loop(const Mesh& m, const Regions& R, Index r) {
  if (R.tris[r].size() == 1) {
    const auto& t = m.tris[R.tris[r][0]];
    return {t[0], t[1], t[2]};
  }
  std::unordered_map<Index, Index> next;
  std::size_t count = 0;
  Index start = kNone;
  for (Index t : R.tris[r]) {
    for (int k = 0; k < 3; ++k) {
      const Index g = m.E.group_of[3 * t + k];
      if (m.E.size(g) == 2 && R.of_tri[m.across(g, t)] == r) continue;  // interior edge
      const Index a = m.tris[t][k], b = m.tris[t][(k + 1) % 3];
      if (!next.emplace(a, b).second) return {};  // the boundary passes a vertex twice
      if (start == kNone) start = a;
      ++count;
    }
  }
  if (start == kNone) return {};
  std::vector<Index> loop;
  Index v = start;
  do {
    loop.push_back(v);
    const auto it = next.find(v);
    if (it == next.end()) return {};
    v = it->second;
  } while (v != start && loop.size() <= count);
  if (loop.size() != count || v != start) return {};  // several loops: holes
  // Drop vertices within plane_tol of the line from the previous kept vertex to the next one.
  std::vector<Index> kept;
  for (std::size_t i = 0; i < loop.size(); ++i) {
    const Vector3d& a = m.P[kept.empty() ? loop.back() : kept.back()];
    const Vector3d& b = m.P[loop[i]];
    const Vector3d& c = m.P[loop[(i + 1) % loop.size()]];
    const Vector3d d1 = b - a, d2 = c - b, ac = c - a;
    const bool straight = d1.dot(d2) > 0.0 && ac.norm() > 0.0 && d1.cross(ac).norm() <= m.plane_tol * ac.norm();
    if (!straight) kept.push_back(loop[i]);
  }
  if (kept.size() < 3) return {};
  return kept;
}

// ------------------------------------------------------------------------------------------
// Sharp-edge chains.

/// A path of sharp pieces through vertices of sharp degree 2 (or a closed loop).
struct Chain {
  std::vector<Index> verts;   // k + 1 vertices; closed when verts.front() == verts.back()
  std::vector<Index> pieces;  // k edge groups
  [[nodiscard]] bool closed() const { return verts.size() > 3 && verts.front() == verts.back(); }
};

/// Rotates a closed chain to start at vertex position s (0 <= s < k).
Chain rotate(const Chain& c, std::size_t s) {
  const std::size_t k = c.pieces.size();
  Chain r;
  for (std::size_t i = 0; i <= k; ++i) r.verts.push_back(c.verts[(s + i) % k]);
  for (std::size_t i = 0; i < k; ++i) r.pieces.push_back(c.pieces[(s + i) % k]);
  return r;
}

std::vector<Vector3d> points_of(const Chain& c, const std::vector<Vector3d>& P) {
  std::vector<Vector3d> Q;
  Q.reserve(c.verts.size());
  for (Index v : c.verts) Q.push_back(P[v]);
  return Q;
}

/// Maximal paths of sharp pieces between vertices whose sharp degree is not 2, then the closed
/// loops left over. `degree` receives the sharp degree of every vertex.
std::vector<Chain> sharp_chains(const Mesh& m, std::vector<std::uint32_t>& degree) {
  const std::size_t G = m.E.groups(), V = m.P.size();
  degree.assign(V, 0);
  std::vector<std::pair<Index, Index>> ends(G, {kNone, kNone});
  for (std::size_t g = 0; g < G; ++g) {
    if (!m.sharp[g]) continue;
    const std::uint64_t key = m.E.half[m.E.first[g]].key;
    ends[g] = {static_cast<Index>(key >> 32), static_cast<Index>(key & 0xFFFFFFFFu)};
    ++degree[ends[g].first];
    ++degree[ends[g].second];
  }
  std::vector<std::size_t> adj_first(V + 1, 0);
  for (std::size_t v = 0; v < V; ++v) adj_first[v + 1] = adj_first[v] + degree[v];
  std::vector<Index> adj(adj_first.back());
  std::vector<std::size_t> fill(adj_first.begin(), adj_first.end() - 1);
  for (std::size_t g = 0; g < G; ++g) {
    if (!m.sharp[g]) continue;
    adj[fill[ends[g].first]++] = static_cast<Index>(g);
    adj[fill[ends[g].second]++] = static_cast<Index>(g);
  }
  std::vector<char> used(G, 0);
  std::vector<Chain> chains;
  auto walk = [&](Index v0, Index g) {
    Chain c;
    c.verts.push_back(v0);
    Index v = v0;
    while (true) {
      used[g] = 1;
      c.pieces.push_back(g);
      v = ends[g].first == v ? ends[g].second : ends[g].first;
      c.verts.push_back(v);
      if (degree[v] != 2 || v == v0) break;
      const Index a = adj[adj_first[v]], b = adj[adj_first[v] + 1];
      g = a == g ? b : a;
      if (used[g]) break;
    }
    chains.push_back(std::move(c));
  };
  for (std::size_t v = 0; v < V; ++v) {
    if (degree[v] == 2 || degree[v] == 0) continue;
    for (std::size_t i = adj_first[v]; i < adj_first[v + 1]; ++i) {
      if (!used[adj[i]]) walk(static_cast<Index>(v), adj[i]);
    }
  }
  for (std::size_t g = 0; g < G; ++g) {
    if (m.sharp[g] && !used[g]) walk(ends[g].first, static_cast<Index>(g));  // closed loops
  }
  return chains;
}

/// A line or an arc: pieces [seg.begin, seg.end) of chains[chain].
struct Feature {
  std::size_t chain;
  Segment seg;
};

/// Splits every chain into arcs and straight lines. A closed loop is first tried as a full
/// circle; otherwise it is rotated to start where a segment truly begins (the end of an arc
/// found from its straightest vertex, or else its sharpest corner), so that no arc or line is
/// cut in two by the arbitrary start of the loop.
std::vector<Feature> segment_chains(std::vector<Chain>& chains, const std::vector<std::uint32_t>& degree,
                                    const std::vector<Vector3d>& P, const MeshImportOptions& opt) {
  std::vector<Feature> features;
  auto emit = [&](std::size_t ci) {
    for (Segment& s : segment_open(points_of(chains[ci], P), opt)) features.push_back({ci, std::move(s)});
  };
  for (std::size_t ci = 0; ci < chains.size(); ++ci) {
    const Chain& c = chains[ci];
    const std::size_t k = c.pieces.size();
    if (!c.closed()) {
      emit(ci);
      continue;
    }
    const std::vector<Vector3d> Q = points_of(c, P);
    if (opt.detect_circles) {
      if (auto fit = full_circle(Q, opt)) {
        features.push_back({ci, Segment{0, k, fit}});
        continue;
      }
    }
    if (degree[c.verts.front()] != 2) {  // a loop through a junction starts and ends there
      emit(ci);
      continue;
    }
    std::vector<double> turns(k);
    for (std::size_t i = 0; i < k; ++i) {
      const Vector3d a = (Q[i == 0 ? k : i] - Q[i == 0 ? k - 1 : i - 1]).normalized();
      const Vector3d b = (Q[i + 1] - Q[i]).normalized();
      turns[i] = std::acos(std::clamp(a.dot(b), -1.0, 1.0));
    }
    std::size_t start = static_cast<std::size_t>(std::max_element(turns.begin(), turns.end()) - turns.begin());
    if (opt.detect_circles && k > static_cast<std::size_t>(opt.min_circle_segments)) {
      const std::size_t s0 = static_cast<std::size_t>(std::min_element(turns.begin(), turns.end()) - turns.begin());
      bool found = false;
      for (std::size_t s : {s0, (s0 + k / 2) % k}) {
        for (const Segment& a : find_arcs(points_of(rotate(c, s), P), opt)) {
          if (a.end < k || a.begin > 0) {
            start = (s + (a.end < k ? a.end : a.begin)) % k;
            found = true;
            break;
          }
        }
        if (found) break;
      }
    }
    chains[ci] = rotate(c, start);
    emit(ci);
  }
  return features;
}

/// Picks the face with the largest weight (smallest index on ties), other than `exclude`.
Index dominant(const std::unordered_map<Index, double>& w, Index exclude) {
  Index b = kNone;
  double bw = -1.0;
  for (const auto& [f, x] : w) {
    if (f != exclude && (x > bw || (x == bw && f < b))) {
      b = f;
      bw = x;
    }
  }
  return b;
}

/// The CircleArc of an arc feature: the face lying in the circle's plane along it (if any) gives
/// the arc's face and normal; otherwise the normal points away from the surface meeting it.
CircleArc make_arc(const Mesh& m, const Chain& c, const Segment& seg, const std::vector<Index>& face_of) {
  const CircleFit& cf = *seg.circle;
  const double cos_in_plane = std::cos(kArcFaceAngle);
  std::unordered_map<Index, double> coplanar;
  std::unordered_map<Index, double> side;  // face -> sum of its triangles' normal . cf.normal
  double off_plane = 0.0;
  for (std::size_t i = seg.begin; i < seg.end; ++i) {
    const Index g = c.pieces[i];
    const double len = (m.P[c.verts[i + 1]] - m.P[c.verts[i]]).norm();
    for (std::size_t h = m.E.first[g]; h < m.E.first[g + 1]; ++h) {
      const Index t = m.E.half[h].tri;
      const double d = m.N[t].dot(cf.normal);
      if (std::abs(d) > cos_in_plane) {
        if (face_of[t] != kNone) {
          coplanar[face_of[t]] += len;
          side[face_of[t]] += d;
        }
      } else {
        const Vector3d centroid = (m.P[m.tris[t][0]] + m.P[m.tris[t][1]] + m.P[m.tris[t][2]]) / 3.0;
        off_plane += len * (centroid - cf.centre).dot(cf.normal);
      }
    }
  }
  CircleArc arc;
  arc.center = cf.centre;
  arc.radius = cf.radius;
  arc.face = dominant(coplanar, kNone);
  Vector3d n = cf.normal;
  if (arc.face != kNone ? side[arc.face] < 0.0 : off_plane > 0.0) n = -n;
  arc.normal = n;
  auto radial = [&](Index v) {
    const Vector3d d = m.P[v] - cf.centre;
    return Vector3d((d - d.dot(n) * n).normalized());
  };
  if (seg.begin == 0 && seg.end == c.pieces.size() && c.closed()) {
    arc.x_axis = radial(c.verts[0]);
    arc.start = 0.0;
    arc.end = kTwoPi;
    return arc;
  }
  double swept = 0.0;
  for (std::size_t i = seg.begin; i < seg.end; ++i) {
    const Vector3d a = radial(c.verts[i]), b = radial(c.verts[i + 1]);
    swept += std::atan2(a.cross(b).dot(n), a.dot(b));
  }
  arc.x_axis = swept >= 0.0 ? radial(c.verts[seg.begin]) : radial(c.verts[seg.end]);
  arc.start = 0.0;
  arc.end = std::min(std::abs(swept), kTwoPi);
  return arc;
}

}  // namespace

Expected<Model> mesh_to_model(const TriangleMesh& mesh, const std::string& source, const MeshImportOptions& opt,
                              MeshImportStats* stats) {
  const auto t0 = Clock::now();
  MeshImportStats st_local;
  MeshImportStats& st = stats ? *stats : st_local;
  if (mesh.triangles.empty()) return file_error(source, "the mesh contains no triangles");
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    if (!mesh.vertices[i].allFinite()) return file_error(source, fmt::format("vertex {} has a non-finite coordinate", i));
  }
  for (const auto& t : mesh.triangles) {
    for (Index v : t) {
      if (v >= mesh.vertices.size())
        return file_error(source, fmt::format("a triangle refers to vertex {} of {}", v, mesh.vertices.size()));
    }
  }
  if (!(opt.sharp_angle >= 0.0) || !(opt.weld_tolerance >= 0.0) || !(opt.collinear_angle >= 0.0) ||
      !(opt.circle_tolerance > 0.0) || !(opt.coplanar_angle >= 0.0))
    return file_error(source, "invalid mesh import options (angles and tolerances must be >= 0)");

  // 1. Clean mesh, sharp edges; 2. coplanar regions; 3. chains of sharp pieces -> lines, arcs.
  auto prepared = prepare(mesh, source, opt, st);
  if (!prepared) return prepared.error();
  const Mesh& m = *prepared;
  const Regions R = grow_regions(m, opt);
  std::vector<std::uint32_t> degree;
  std::vector<Chain> chains = sharp_chains(m, degree);
  const std::vector<Feature> features = segment_chains(chains, degree, m.P, opt);

  // 4. Junctions: face loop vertices (all triangle corners of non-simple regions), line ends.
  std::vector<char> needed(m.P.size(), 0);
  for (std::size_t r = 0; r < R.tris.size(); ++r) {
    for (Index v : R.loop[r]) needed[v] = 1;
    if (R.loop[r].empty()) {
      for (Index t : R.tris[r]) {
        for (Index v : m.tris[t]) needed[v] = 1;
      }
    }
  }
  for (const Feature& f : features) {
    if (f.seg.circle) continue;
    needed[chains[f.chain].verts[f.seg.begin]] = 1;
    needed[chains[f.chain].verts[f.seg.end]] = 1;
  }
  ModelBuilder builder(std::filesystem::path(source).stem().string());
  std::vector<Index> junction_of(m.P.size(), kNone);
  for (std::size_t v = 0; v < m.P.size(); ++v) {
    if (needed[v]) junction_of[v] = builder.add_junction(m.P[v]);
  }
  auto to_junctions = [&](const std::vector<Index>& verts) {
    std::vector<Index> j;
    j.reserve(verts.size());
    for (Index v : verts) j.push_back(junction_of[v]);
    return j;
  };

  // 5. Faces: merged polygons, or the triangles of regions that are not simple polygons.
  std::vector<Index> face_of(m.tris.size(), kNone);
  for (std::size_t r = 0; r < R.tris.size(); ++r) {
    if (!R.loop[r].empty()) {
      if (auto fi = builder.add_face(to_junctions(R.loop[r]), {}, kFacePlanarity, FaceEdges::kSkip)) {
        for (Index t : R.tris[r]) face_of[t] = *fi;
        continue;
      }
    }
    for (Index t : R.tris[r]) {
      const auto& tv = m.tris[t];
      if (auto fi = builder.add_face(to_junctions({tv[0], tv[1], tv[2]}), {}, kFacePlanarity, FaceEdges::kSkip))
        face_of[t] = *fi;
    }
  }

  // 6. Lines, linked to their dominant faces on either side (weighted by piece length), and arcs.
  std::unordered_map<Index, double> w_left, w_right;
  for (const Feature& f : features) {
    const Chain& c = chains[f.chain];
    if (f.seg.circle) {
      builder.add_arc(make_arc(m, c, f.seg, face_of));
      ++st.circles;
      continue;
    }
    w_left.clear();
    w_right.clear();
    for (std::size_t i = f.seg.begin; i < f.seg.end; ++i) {
      const Index g = c.pieces[i];
      const Index va = c.verts[i];
      const double len = (m.P[c.verts[i + 1]] - m.P[va]).norm();
      for (std::size_t h = m.E.first[g]; h < m.E.first[g + 1]; ++h) {
        const Index fi = face_of[m.E.half[h].tri];
        if (fi == kNone) continue;
        const bool left = directed(m.tris, m.E.half[h]).first == va;  // the face runs along the line
        (left ? w_left : w_right)[fi] += len;
      }
    }
    Index a = c.verts[f.seg.begin], b = c.verts[f.seg.end];
    Index left = dominant(w_left, kNone);
    Index right = dominant(w_right, left);
    if (left == kNone && right != kNone) {  // keep face_left filled: run the line the other way
      std::swap(a, b);
      left = right;
      right = kNone;
    }
    if (a == b) continue;
    const Index li = builder.add_line(junction_of[a], junction_of[b]);
    auto linked = builder.set_line_faces(li, left, right);
    if (!linked) return file_error(source, linked.error().message);
  }

  st.faces = builder.face_count();
  st.lines = builder.line_count();
  st.junctions = builder.junction_count();
  auto model = std::move(builder).build();
  st.extract_ms = ms_since(t0);
  if (!model) return file_error(source, model.error().message);
  return model;
}

Expected<TriangleMesh> read_triangle_mesh(const std::string& path, const MeshImportOptions& opt,
                                          MeshImportStats* stats) {
  const auto t0 = Clock::now();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return file_error(path, "no such file");
  if (std::filesystem::is_directory(path, ec)) return file_error(path, "is a directory, not a mesh file");
  if (!(opt.scale > 0.0) || !std::isfinite(opt.scale)) return file_error(path, "the import scale must be > 0");

  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices);
  if (scene == nullptr) {
    const std::string why = importer.GetErrorString();
    return file_error(path, "cannot read the mesh: " + (why.empty() ? std::string("unknown error") : why));
  }
  TriangleMesh mesh;
  const Eigen::Matrix3d R = opt.T_obj_file.rotation();
  const Vector3d& t = opt.T_obj_file.translation();
  auto add_mesh = [&](const aiMesh& m, const Eigen::Matrix4d& M) -> Expected<void> {
    const auto base = static_cast<Index>(mesh.vertices.size());
    for (unsigned i = 0; i < m.mNumVertices; ++i) {
      const aiVector3D& v = m.mVertices[i];
      const Eigen::Vector4d pf = M * Eigen::Vector4d(v.x, v.y, v.z, 1.0);
      const Vector3d p = R * (opt.scale * pf.head<3>()) + t;
      if (!p.allFinite())
        return file_error(path, fmt::format("vertex {} of mesh '{}' has a non-finite coordinate", i, m.mName.C_Str()));
      mesh.vertices.push_back(p);
    }
    for (unsigned f = 0; f < m.mNumFaces; ++f) {
      const aiFace& face = m.mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines
      std::array<Index, 3> tri{};
      bool ok = true;
      for (int k = 0; k < 3; ++k) {
        ok = ok && face.mIndices[k] < m.mNumVertices;
        tri[k] = base + face.mIndices[k];
      }
      if (ok) mesh.triangles.push_back(tri);
    }
    return {};
  };
  // Every mesh instance of the node tree, placed by the accumulated node transforms.
  bool instanced = false;
  if (scene->mRootNode != nullptr) {
    std::vector<std::pair<const aiNode*, Eigen::Matrix4d>> stack{{scene->mRootNode, Eigen::Matrix4d::Identity()}};
    while (!stack.empty()) {
      const auto [node, parent] = stack.back();
      stack.pop_back();
      Eigen::Matrix4d local;
      const aiMatrix4x4& a = node->mTransformation;
      local << a.a1, a.a2, a.a3, a.a4, a.b1, a.b2, a.b3, a.b4, a.c1, a.c2, a.c3, a.c4, a.d1, a.d2, a.d3, a.d4;
      const Eigen::Matrix4d global = parent * local;
      for (unsigned i = 0; i < node->mNumMeshes; ++i) {
        if (node->mMeshes[i] >= scene->mNumMeshes) continue;
        auto ok = add_mesh(*scene->mMeshes[node->mMeshes[i]], global);
        if (!ok) return ok.error();
        instanced = true;
      }
      for (unsigned i = 0; i < node->mNumChildren; ++i) stack.emplace_back(node->mChildren[i], global);
    }
  }
  if (!instanced) {  // meshes without a node tree: take them as they are
    for (unsigned i = 0; i < scene->mNumMeshes; ++i) {
      auto ok = add_mesh(*scene->mMeshes[i], Eigen::Matrix4d::Identity());
      if (!ok) return ok.error();
    }
  }
  if (mesh.triangles.empty()) return file_error(path, "the mesh contains no triangles");
  if (stats) {
    stats->file_vertices = mesh.vertices.size();
    stats->file_triangles = mesh.triangles.size();
    stats->read_ms = ms_since(t0);
  }
  return mesh;
}

Expected<Model> load_mesh(const std::string& path, const MeshImportOptions& opt, MeshImportStats* stats) {
  auto mesh = read_triangle_mesh(path, opt, stats);
  if (!mesh) return mesh.error();
  return mesh_to_model(*mesh, path, opt, stats);
}

}  // namespace v4r::model
