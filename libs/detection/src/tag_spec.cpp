// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/tag_spec.hpp"

#include <array>
#include <charconv>
#include <cmath>

#include <fmt/format.h>

namespace v4r::detection {

namespace {

constexpr std::string_view kFormat = "expected family:id:size_m:\"tx ty tz rx ry rz\"";

Unexpected field_error(const std::string& source, std::string_view field, const std::string& what) {
  return make_error(fmt::format("{}: field '{}': {} ({})", source, field, what, kFormat));
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r' || s.back() == '\n')) s.remove_suffix(1);
  return s;
}

bool parse_double(std::string_view s, double& v) {
  if (s.empty()) return false;
  if (s.front() == '+') s.remove_prefix(1);
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && end == s.data() + s.size() && std::isfinite(v);
}

}  // namespace

const std::vector<std::string>& tag_families() {
  static const std::vector<std::string> kFamilies{"tag36h11",        "tag36h10",        "tag25h9",
                                                  "tag16h5",         "tagStandard41h12", "tagStandard52h13",
                                                  "tagCircle21h7",   "tagCircle49h12",  "tagCustom48h12"};
  return kFamilies;
}

Expected<TagSpec> parse_tag_spec(std::string_view text, const std::string& source) {
  // Four fields split at the first three colons (the pose holds none).
  std::array<std::string_view, 4> f;
  std::size_t n = 0;
  std::string_view rest = trim(text);
  while (n < 3) {
    const std::size_t c = rest.find(':');
    if (c == std::string_view::npos) break;
    f[n++] = trim(rest.substr(0, c));
    rest = rest.substr(c + 1);
  }
  f[n++] = trim(rest);
  constexpr std::array<const char*, 4> kFields{"family", "id", "size_m", "pose"};
  if (f[0].empty()) return field_error(source, "family", "missing");
  if (n < 4) return field_error(source, kFields[n], "missing");
  if (f[3].find(':') != std::string_view::npos) return field_error(source, "pose", "holds a ':' (only four fields)");
  TagSpec s;
  s.family = std::string(f[0]);
  bool known = false;
  for (const std::string& fam : tag_families()) known = known || fam == s.family;
  if (!known) {
    std::string list;
    for (const std::string& fam : tag_families()) list += (list.empty() ? "" : ", ") + fam;
    return field_error(source, "family", fmt::format("unknown tag family '{}' (one of {})", f[0], list));
  }
  {
    const auto [end, ec] = std::from_chars(f[1].data(), f[1].data() + f[1].size(), s.id);
    if (f[1].empty() || ec != std::errc() || end != f[1].data() + f[1].size() || s.id < 0)
      return field_error(source, "id", fmt::format("'{}' is not a tag id (an integer >= 0)", f[1]));
  }
  if (!parse_double(f[2], s.size_m) || s.size_m <= 0.0 || s.size_m > 10.0)
    return field_error(source, "size_m", fmt::format("'{}' is not a tag size in metres (> 0, at most 10)", f[2]));
  constexpr std::array<const char*, 6> kNames{"tx", "ty", "tz", "rx", "ry", "rz"};
  std::array<double, 6> v{};
  std::size_t count = 0;
  std::string_view p = f[3];
  if (p.size() >= 2 && (p.front() == '"' || p.front() == '\'') && p.back() == p.front()) p = p.substr(1, p.size() - 2);
  std::size_t i = 0;
  while (i < p.size()) {
    if (p[i] == ' ' || p[i] == '\t' || p[i] == ',') {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < p.size() && p[j] != ' ' && p[j] != '\t' && p[j] != ',') ++j;
    const std::string_view tok = p.substr(i, j - i);
    if (count == v.size()) return field_error(source, "pose", fmt::format("a seventh number '{}' (six: tx ty tz rx ry rz)", tok));
    if (!parse_double(tok, v[count]))
      return field_error(source, kNames[count], fmt::format("'{}' is not a number ({} in {})", tok, kNames[count],
                                                            count < 3 ? "metres" : "radians"));
    ++count;
    i = j;
  }
  if (count < v.size()) return field_error(source, kNames[count], "missing (six numbers: tx ty tz rx ry rz)");
  s.T_obj_tag = geometry::SE3::from_rvec(Eigen::Vector3d(v[0], v[1], v[2]), Eigen::Vector3d(v[3], v[4], v[5]));
  return s;
}

std::string format_tag_spec(const TagSpec& s) {
  const Eigen::Vector3d t = s.T_obj_tag.translation();
  const Eigen::Vector3d r = s.T_obj_tag.rvec();
  return fmt::format("{}:{}:{:.9g}:{:.9g} {:.9g} {:.9g} {:.9g} {:.9g} {:.9g}", s.family, s.id, s.size_m, t.x(), t.y(),
                     t.z(), r.x(), r.y(), r.z());
}

}  // namespace v4r::detection
