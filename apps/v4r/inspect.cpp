// v4r - robust model-based object tracking. MIT licence.
#include "inspect.hpp"

#include <fmt/format.h>

#include "app.hpp"
#include "plausibility.hpp"

namespace v4r::app {

std::string units_guess(double size_m, bool& plausible) {
  plausible = size_m <= plausibility::kMaxModelSize && size_m >= 0.002;
  if (size_m > plausibility::kMaxModelSize)
    return fmt::format("millimetres? ({:.4g} m across as metres, {:.4g} m as millimetres: --model-units mm)", size_m,
                       size_m * 1e-3);
  if (size_m < 0.002) return fmt::format("very small in metres ({:.3g} m across): a unit larger than metres?", size_m);
  return "metres";
}

std::string describe_model(const model::Model& m, bool verbose) {
  std::string s = fmt::format("model {}: {} junctions, {} lines, {} arcs, {} faces, {} cylinders, bounding radius {:.4f} m\n",
                              m.name(), m.junctions().size(), m.lines().size(), m.arcs().size(), m.faces().size(),
                              m.cylinders().size(), m.bounding_radius());
  const Extent e = model_extent(m);
  const Eigen::Vector3d size = e.size();
  s += fmt::format("extent: {:.4f} x {:.4f} x {:.4f} m (x y z)\n", size.x(), size.y(), size.z());
  s += fmt::format("bounding box: min ({:.4f}, {:.4f}, {:.4f}) max ({:.4f}, {:.4f}, {:.4f}) m\n", e.min.x(), e.min.y(),
                   e.min.z(), e.max.x(), e.max.y(), e.max.z());
  bool plausible = true;
  s += fmt::format("units: {}\n", units_guess(size.maxCoeff(), plausible));
  if (!verbose) return s;
  for (std::size_t i = 0; i < m.faces().size(); ++i) {
    const model::Face& f = m.faces()[i];
    s += fmt::format("face {}{}: {} corners, normal ({:.3f}, {:.3f}, {:.3f})\n", i,
                     f.attr.name.empty() ? "" : " " + f.attr.name, f.loop.size(), f.normal.x(), f.normal.y(),
                     f.normal.z());
  }
  for (std::size_t i = 0; i < m.lines().size(); ++i) {
    const model::LineEdge& l = m.lines()[i];
    const Eigen::Vector3d a = m.line_point_a(static_cast<model::Index>(i)), b = m.line_point_b(static_cast<model::Index>(i));
    s += fmt::format("line {}{}: ({:.4f}, {:.4f}, {:.4f}) - ({:.4f}, {:.4f}, {:.4f}), {:.4f} m\n", i,
                     l.attr.name.empty() ? "" : " " + l.attr.name, a.x(), a.y(), a.z(), b.x(), b.y(), b.z(),
                     (b - a).norm());
  }
  for (std::size_t i = 0; i < m.arcs().size(); ++i) {
    const model::CircleArc& c = m.arcs()[i];
    s += fmt::format("circle {}{}: centre ({:.4f}, {:.4f}, {:.4f}), radius {:.4f} m\n", i,
                     c.attr.name.empty() ? "" : " " + c.attr.name, c.center.x(), c.center.y(), c.center.z(), c.radius);
  }
  return s;
}

int cmd_inspect(const std::string& path, double scale, bool verbose, const model::CaoReadOptions& cao) {
  std::vector<Error> warnings;
  auto m = load_model(path, scale, cao, &warnings);
  for (const Error& w : warnings) fmt::print(stderr, "v4r inspect-model: warning: {}\n", w.to_string());
  if (!m) {
    fmt::print(stderr, "v4r inspect-model: error: {}\n", m.error().to_string());
    return 1;
  }
  fmt::print("{}", describe_model(**m, verbose));
  for (const std::string& w : check_model_size(**m, path)) fmt::print(stderr, "v4r inspect-model: warning: {}\n", w);
  return 0;
}

}  // namespace v4r::app
