// v4r - robust model-based object tracking. MIT licence.
#pragma once

// Internal: splitting a protocol line into words, reading numbers, and checking the key=value
// arguments of one command with a sticky first error. Not installed; used by commands.cpp and
// events.cpp.

#include <array>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "v4r/protocol/protocol.hpp"

namespace v4r::protocol::detail {

/// \brief One word of a line: a positional word (`Display on`) or `key=value` (value unescaped).
struct Token {
  bool positional = false;
  std::string key;            ///< empty for a positional word
  std::string value;          ///< the word itself for a positional word
  std::size_t column = 0;     ///< 1-based column of the word
  std::size_t value_column = 0;  ///< 1-based column of the value
};

/// Strips one trailing CR.
std::string_view strip_cr(std::string_view line);

/// The first word of the line if it looks like a command ([A-Za-z][A-Za-z0-9_]{0,63}), else "?".
std::string command_word(std::string_view line);

/// Splits the line (CR already stripped) into tokens. Checks, in this order: length (if
/// max_bytes > 0), bytes, blank, syntax. `command` names the line in the error.
std::optional<ParseError> lex(std::string_view line, std::size_t max_bytes, std::vector<Token>& out);

/// \brief Outcome of reading a number.
enum class NumStatus { kOk, kBad, kNotFinite };
/// Decimal floating point `[+-]?(d+[.d*]|.d+)([eE][+-]?d+)?`; nan/inf and overflow give
/// kNotFinite, underflow reads as (signed) zero or a subnormal.
NumStatus parse_double(std::string_view s, double& out);
/// Decimal digits only, fitting in 64 bits.
bool parse_uint(std::string_view s, std::uint64_t& out);

/// Echo of user text in a message: at most 40 characters, with "..." when cut.
std::string echo(std::string_view text);

/// \brief Reads the arguments of one message; the first problem found is kept, later calls then
/// return defaults. Order of checks: keys left to right (duplicate, unknown, unexpected word),
/// then required keys, then values in the order they are read.
class Args {
 public:
  Args(std::string command, std::vector<Token> tokens) : command_(std::move(command)), tokens_(std::move(tokens)) {}

  [[nodiscard]] bool ok() const { return !error_.has_value(); }
  [[nodiscard]] const ParseError& error() const { return *error_; }
  void fail(std::string_view code, std::string message, std::size_t column);

  /// Duplicates, keys outside `allowed` (ignored instead when `ignore_unknown`), and positional
  /// words beyond `positionals` allowed ones.
  void check_keys(std::initializer_list<std::string_view> allowed, std::size_t positionals = 0,
                  bool ignore_unknown = false);
  /// missing_argument for the first absent key.
  void require(std::initializer_list<std::string_view> keys);

  [[nodiscard]] const Token* find(std::string_view key) const;
  [[nodiscard]] bool has(std::string_view key) const { return find(key) != nullptr; }
  /// The positional words, in order.
  [[nodiscard]] std::vector<const Token*> positional() const;

  std::string name(std::string_view key);   ///< required, [A-Za-z0-9_.-]{1,64}
  std::string text(std::string_view key);   ///< required, any non-empty text
  double number(std::string_view key);      ///< required, finite
  std::uint64_t whole(std::string_view key);  ///< required, non-negative integer
  template <std::size_t N>
  std::array<double, N> vector(std::string_view key, std::string_view what);  ///< N finite numbers
  /// Required value that must be one of `words`; returns its index.
  std::size_t word(std::string_view key, std::initializer_list<std::string_view> words);

 private:
  const Token* need(std::string_view key);
  bool read_number(std::string_view text, std::string_view key, std::size_t column, std::string_view what,
                   double& out);

  std::string command_;
  std::vector<Token> tokens_;
  std::optional<ParseError> error_;
};

template <std::size_t N>
std::array<double, N> Args::vector(std::string_view key, std::string_view what) {
  std::array<double, N> v{};
  const Token* t = need(key);
  if (t == nullptr) return v;
  std::size_t count = 1;
  for (char c : t->value) count += (c == ',') ? 1 : 0;
  if (count != N) {
    fail(code::kBadVector,
         std::string(key) + "=: expected " + std::to_string(N) + " comma-separated numbers " + std::string(what) +
             ", got " + std::to_string(count),
         t->value_column);
    return v;
  }
  std::size_t start = 0;
  for (std::size_t i = 0; i < N; ++i) {
    std::size_t end = t->value.find(',', start);
    if (end == std::string::npos) end = t->value.size();
    if (!read_number(std::string_view(t->value).substr(start, end - start), key, t->value_column + start,
                     "component " + std::to_string(i + 1), v[i]))
      return v;
    start = end + 1;
  }
  return v;
}

}  // namespace v4r::protocol::detail
