// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>
#include <utility>
#include <variant>

#include <fmt/format.h>

namespace v4r {

/// \brief An error with the context a user needs to fix the input: where (file, line, column or
/// field) and what. Line and column are 1-based; 0 means "not applicable".
struct Error {
  std::string message;
  std::string file;   ///< file name, or the source of the input ("<protocol>", "<string>")
  int line = 0;
  int column = 0;
  std::string field;  ///< key or field name, where one applies

  /// "file:line:column: field: message", leaving out what is not set.
  [[nodiscard]] std::string to_string() const {
    std::string s;
    if (!file.empty()) {
      s += file;
      if (line > 0) {
        s += fmt::format(":{}", line);
        if (column > 0) s += fmt::format(":{}", column);
      }
      s += ": ";
    }
    if (!field.empty()) s += field + ": ";
    s += message;
    return s;
  }
};

/// \brief Tag wrapper used to build an Expected holding an error: `return Unexpected{err};`.
struct Unexpected {
  Error error;
};

/// \brief A value or an Error (C++23 std::expected, reduced to what v4r needs).
template <typename T>
class [[nodiscard]] Expected {
 public:
  Expected(T value) : v_(std::move(value)) {}  // NOLINT: implicit by design
  Expected(Unexpected u) : v_(std::move(u.error)) {}  // NOLINT
  Expected(Error e) : v_(std::move(e)) {}  // NOLINT

  [[nodiscard]] bool has_value() const { return v_.index() == 0; }
  explicit operator bool() const { return has_value(); }

  T& value() & { return std::get<0>(v_); }
  const T& value() const& { return std::get<0>(v_); }
  T&& value() && { return std::get<0>(std::move(v_)); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }

  [[nodiscard]] const Error& error() const { return std::get<1>(v_); }

 private:
  std::variant<T, Error> v_;
};

/// \brief Expected<void>: success or an Error.
template <>
class [[nodiscard]] Expected<void> {
 public:
  Expected() = default;
  Expected(Unexpected u) : err_(std::move(u.error)), ok_(false) {}  // NOLINT
  Expected(Error e) : err_(std::move(e)), ok_(false) {}  // NOLINT
  [[nodiscard]] bool has_value() const { return ok_; }
  explicit operator bool() const { return ok_; }
  [[nodiscard]] const Error& error() const { return err_; }

 private:
  Error err_;
  bool ok_ = true;
};

/// Shorthand: `return make_error("file.cao", 3, 7, "expected a number");`
inline Unexpected make_error(std::string file, int line, int column, std::string message) {
  return Unexpected{Error{std::move(message), std::move(file), line, column, {}}};
}
inline Unexpected make_error(std::string message) { return Unexpected{Error{std::move(message), {}, 0, 0, {}}}; }

}  // namespace v4r
