// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "v4r/core/expected.hpp"

namespace v4r {

/// \brief A table of named tunable parameters bound to the fields of parameter structs (each
/// with its range, unit and meaning), so that configuration files, the command line and the
/// server's SetParam/GetParam/ListParams all reach every parameter by one dotted name
/// (`track.rows`) with one validation.
class ParamRegistry {
 public:
  struct Entry {
    std::string name;
    std::variant<int*, double*, float*, bool*> field;
    double lo = 0.0, hi = 0.0;  ///< inclusive range (numbers)
    std::string unit;           ///< "px", "rad", "m", "" ...
    std::string doc;
    std::string default_value;  ///< value when registered
  };

  void add(std::string name, int* field, int lo, int hi, std::string unit, std::string doc);
  void add(std::string name, double* field, double lo, double hi, std::string unit, std::string doc);
  void add(std::string name, float* field, double lo, double hi, std::string unit, std::string doc);
  void add(std::string name, bool* field, std::string doc);

  /// Parses `value` for parameter `name`, checks its range and sets it. Errors name the field:
  /// unknown parameter (with the nearest known name), not a number, out of range.
  Expected<void> set(std::string_view name, std::string_view value);
  /// Current value as text.
  Expected<std::string> get(std::string_view name) const;
  [[nodiscard]] const std::vector<Entry>& entries() const { return entries_; }
  [[nodiscard]] const Entry* find(std::string_view name) const;
  /// Effective configuration as YAML, nested by the dotted names, with unit and meaning as comments.
  [[nodiscard]] std::string to_yaml() const;

  static std::string format(const Entry& e);

 private:
  std::vector<Entry> entries_;
};

}  // namespace v4r
