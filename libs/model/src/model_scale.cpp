// v4r - robust model-based object tracking. MIT licence.
#include "v4r/model/model_scale.hpp"

#include <cmath>

#include <fmt/format.h>

namespace v4r::model {

/// A copy of `m` with every length multiplied by `s` (junctions, circles, cylinders); the
/// topology (lines, faces and their adjacency) is kept as it is.
Expected<Model> scaled(const Model& m, double s) {
  if (!(s > 0.0) || !std::isfinite(s)) return make_error(fmt::format("scale must be a positive number, got {}", s));
  ModelBuilder b(m.name());
  for (const Junction& j : m.junctions()) b.add_junction(j.p * s, j.attr);
  for (const LineEdge& e : m.lines()) b.add_line(e.a, e.b, e.attr);
  for (const Face& f : m.faces()) {
    auto fi = b.add_face(f.loop, f.attr, 1e9, FaceEdges::kSkip);  // planarity was checked on load
    if (!fi) return fi.error();
  }
  for (std::size_t i = 0; i < m.lines().size(); ++i) {
    auto r = b.set_line_faces(static_cast<Index>(i), m.lines()[i].face_left, m.lines()[i].face_right);
    if (!r) return r.error();
  }
  // add_cylinder adds the two rim circles itself: the original's rims are not copied twice.
  std::vector<bool> rim(m.arcs().size(), false);
  for (const Cylinder& c : m.cylinders()) {
    b.add_cylinder(Cylinder{c.p1 * s, c.p2 * s, c.radius * s, c.attr});
    for (std::size_t i = 0; i < m.arcs().size(); ++i) {
      const CircleArc& a = m.arcs()[i];
      if (!rim[i] && a.face == kNone && a.radius == c.radius && (a.center == c.p1 || a.center == c.p2))
        rim[i] = true;
    }
  }
  for (std::size_t i = 0; i < m.arcs().size(); ++i) {
    if (rim[i]) continue;
    CircleArc a = m.arcs()[i];
    a.center *= s;
    a.radius *= s;
    b.add_arc(a);
  }
  return std::move(b).build();
}

}  // namespace v4r::model
