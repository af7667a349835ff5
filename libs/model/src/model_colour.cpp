// v4r - robust model-based object tracking. MIT licence.
#include "v4r/model/model_colour.hpp"

#include <charconv>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <fmt/format.h>

namespace v4r::model {

Expected<Eigen::Vector3f> parse_colour(std::string_view spec, const std::string& source) {
  Eigen::Vector3f rgb;
  std::size_t start = 0;
  for (int c = 0; c < 3; ++c) {
    const std::size_t comma = spec.find(',', start);
    if (c < 2 && comma == std::string_view::npos)
      return make_error(source, 0, 0, fmt::format("'{}': expected R,G,B, three numbers in 0..1 (e.g. 0.2,0.6,0.1)", spec));
    if (c == 2 && comma != std::string_view::npos)
      return make_error(source, 0, 0, fmt::format("'{}': expected three values R,G,B, found more", spec));
    const std::string_view part = spec.substr(start, c == 2 ? std::string_view::npos : comma - start);
    double v = 0.0;
    const auto [ptr, ec] = std::from_chars(part.data(), part.data() + part.size(), v);
    if (part.empty() || ec != std::errc() || ptr != part.data() + part.size() || !(v >= 0.0 && v <= 1.0))
      return make_error(source, 0, 0, fmt::format("'{}': component {} must be a number in 0..1, found '{}'", spec, "RGB"[c], part));
    rgb[c] = static_cast<float>(v);
    start = comma + 1;
  }
  return rgb;
}

Model with_face_colour(const Model& m, const Eigen::Vector3f& rgb) {
  Model out = m;
  for (Face& f : out.faces_) f.attr.colour = rgb;
  for (Cylinder& c : out.cylinders_) c.attr.colour = rgb;
  return out;
}

double face_area(const Model& m, const Face& f) {
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  const auto& J = m.junctions();
  for (std::size_t i = 0; i < f.loop.size(); ++i)
    s += J[f.loop[i]].p.cross(J[f.loop[(i + 1) % f.loop.size()]].p);
  return 0.5 * s.norm();
}

std::optional<Eigen::Vector3f> dominant_face_colour(const Model& m) {
  std::vector<std::pair<Eigen::Vector3f, double>> areas;  // colour, summed area
  for (const Face& f : m.faces()) {
    if (!f.attr.colour) continue;
    const double a = face_area(m, f);
    bool found = false;
    for (auto& [c, sum] : areas)
      if ((c - *f.attr.colour).cwiseAbs().maxCoeff() < 1e-6f) {
        sum += a;
        found = true;
        break;
      }
    if (!found) areas.emplace_back(*f.attr.colour, a);
  }
  if (areas.empty()) return std::nullopt;
  std::size_t best = 0;
  for (std::size_t i = 1; i < areas.size(); ++i)
    if (areas[i].second > areas[best].second) best = i;
  return areas[best].first;
}

}  // namespace v4r::model
