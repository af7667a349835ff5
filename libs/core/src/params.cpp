// v4r - robust model-based object tracking. MIT licence.
#include "v4r/core/params.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

#include <fmt/format.h>

namespace v4r {

namespace {

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

Unexpected field_error(std::string_view name, std::string message) {
  Error e;
  e.field = std::string(name);
  e.message = std::move(message);
  return Unexpected{std::move(e)};
}

}  // namespace

void ParamRegistry::add(std::string name, int* field, int lo, int hi, std::string unit, std::string doc) {
  entries_.push_back(Entry{std::move(name), field, double(lo), double(hi), std::move(unit), std::move(doc), {}});
  entries_.back().default_value = format(entries_.back());
}
void ParamRegistry::add(std::string name, double* field, double lo, double hi, std::string unit, std::string doc) {
  entries_.push_back(Entry{std::move(name), field, lo, hi, std::move(unit), std::move(doc), {}});
  entries_.back().default_value = format(entries_.back());
}
void ParamRegistry::add(std::string name, float* field, double lo, double hi, std::string unit, std::string doc) {
  entries_.push_back(Entry{std::move(name), field, lo, hi, std::move(unit), std::move(doc), {}});
  entries_.back().default_value = format(entries_.back());
}
void ParamRegistry::add(std::string name, bool* field, std::string doc) {
  entries_.push_back(Entry{std::move(name), field, 0, 1, "", std::move(doc), {}});
  entries_.back().default_value = format(entries_.back());
}

const ParamRegistry::Entry* ParamRegistry::find(std::string_view name) const {
  for (const Entry& e : entries_)
    if (e.name == name) return &e;
  return nullptr;
}

std::string ParamRegistry::format(const Entry& e) {
  return std::visit(
      [](auto* p) -> std::string {
        using T = std::remove_pointer_t<decltype(p)>;
        if constexpr (std::is_same_v<T, bool>) {
          return *p ? "true" : "false";
        } else if constexpr (std::is_same_v<T, int>) {
          return std::to_string(*p);
        } else {
          return fmt::format("{}", static_cast<double>(*p));
        }
      },
      e.field);
}

Expected<void> ParamRegistry::set(std::string_view name, std::string_view value) {
  const Entry* e = find(name);
  if (!e) {
    std::string best;
    std::size_t best_d = 4;
    for (const Entry& c : entries_) {
      const std::size_t d = edit_distance(name, c.name);
      if (d < best_d) {
        best_d = d;
        best = c.name;
      }
    }
    return field_error(name, best.empty() ? "unknown parameter" : fmt::format("unknown parameter (did you mean '{}'?)", best));
  }
  const std::string_view v = trim(value);
  if (auto* pb = std::get_if<bool*>(&e->field)) {
    if (v == "true" || v == "1" || v == "on" || v == "yes") {
      **pb = true;
    } else if (v == "false" || v == "0" || v == "off" || v == "no") {
      **pb = false;
    } else {
      return field_error(name, fmt::format("expected true or false, got '{}'", v));
    }
    return {};
  }
  double x = 0.0;
  const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (ec != std::errc() || ptr != v.data() + v.size() || v.empty())
    return field_error(name, fmt::format("expected a number, got '{}'", v));
  if (!std::isfinite(x)) return field_error(name, fmt::format("expected a finite number, got '{}'", v));
  if (x < e->lo || x > e->hi)
    return field_error(name, fmt::format("{} is out of range [{}, {}]{}", v, e->lo, e->hi, e->unit.empty() ? "" : " " + e->unit));
  if (auto* pi = std::get_if<int*>(&e->field)) {
    if (x != std::floor(x)) return field_error(name, fmt::format("expected a whole number, got '{}'", v));
    **pi = static_cast<int>(x);
  } else if (auto* pd = std::get_if<double*>(&e->field)) {
    **pd = x;
  } else if (auto* pf = std::get_if<float*>(&e->field)) {
    **pf = static_cast<float>(x);
  }
  return {};
}

Expected<std::string> ParamRegistry::get(std::string_view name) const {
  const Entry* e = find(name);
  if (!e) return field_error(name, "unknown parameter");
  return format(*e);
}

std::string ParamRegistry::to_yaml() const {
  std::string out;
  std::vector<std::string> open;  // path of the mapping currently open
  // Grouped by name, so that every mapping is written once.
  std::vector<const Entry*> sorted;
  for (const Entry& e : entries_) sorted.push_back(&e);
  std::stable_sort(sorted.begin(), sorted.end(), [](const Entry* a, const Entry* b) {
    return a->name.substr(0, a->name.rfind('.')) < b->name.substr(0, b->name.rfind('.'));
  });
  for (const Entry* ep : sorted) {
    const Entry& e = *ep;
    std::vector<std::string> parts;
    std::size_t start = 0;
    for (std::size_t i = 0; i <= e.name.size(); ++i) {
      if (i == e.name.size() || e.name[i] == '.') {
        parts.emplace_back(e.name.substr(start, i - start));
        start = i + 1;
      }
    }
    std::size_t common = 0;
    while (common < open.size() && common + 1 < parts.size() && open[common] == parts[common]) ++common;
    open.resize(common);
    for (std::size_t d = common; d + 1 < parts.size(); ++d) {
      out += std::string(2 * d, ' ') + parts[d] + ":\n";
      open.push_back(parts[d]);
    }
    const std::size_t depth = parts.size() - 1;
    std::string line = std::string(2 * depth, ' ') + parts.back() + ": " + format(e);
    std::string comment = e.doc;
    if (!e.unit.empty()) comment += " [" + e.unit + "]";
    if (!std::holds_alternative<bool*>(e.field)) comment += fmt::format(" ({} .. {})", e.lo, e.hi);
    out += fmt::format("{:<40} # {}\n", line, comment);
  }
  return out;
}

}  // namespace v4r
