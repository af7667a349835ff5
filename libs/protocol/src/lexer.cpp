// v4r - robust model-based object tracking. MIT licence.
#include "lexer.hpp"

#include <charconv>
#include <cstdio>

namespace v4r::protocol::detail {
namespace {

bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_alpha(char c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }
bool is_printable(unsigned char c) { return c >= 0x20 && c <= 0x7E; }
bool is_word_char(char c) { return is_alpha(c) || is_digit(c) || c == '_'; }
bool is_key_char(char c) { return is_word_char(c) || c == '.' || c == '-'; }

std::string col(std::size_t column) { return " (column " + std::to_string(column) + ")"; }

ParseError error_at(std::string command, std::string_view code, std::string message, std::size_t column) {
  ParseError e;
  e.command = std::move(command);
  e.code = std::string(code);
  e.message = std::move(message);
  if (column > 0) e.message += col(column);
  e.column = column;
  return e;
}

// Lower-case copy for the nan/inf check.
bool equals_lower(std::string_view s, std::string_view lower) {
  if (s.size() != lower.size()) return false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    char c = s[i];
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
    if (c != lower[i]) return false;
  }
  return true;
}

}  // namespace

std::string_view strip_cr(std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  return line;
}

std::string command_word(std::string_view line) {
  std::size_t i = 0;
  while (i < line.size() && line[i] == ' ') ++i;
  std::size_t start = i;
  if (i >= line.size() || !is_alpha(line[i])) return "?";
  while (i < line.size() && is_word_char(line[i])) ++i;
  if (i - start > kMaxNameBytes) return "?";
  if (i < line.size() && line[i] != ' ') return "?";
  return std::string(line.substr(start, i - start));
}

std::string echo(std::string_view text) {
  constexpr std::size_t kMax = 40;
  std::string s;
  for (std::size_t i = 0; i < text.size() && i < kMax; ++i)
    s += is_printable(static_cast<unsigned char>(text[i])) ? text[i] : '?';
  if (text.size() > kMax) s += "...";
  return s;
}

std::optional<ParseError> lex(std::string_view line, std::size_t max_bytes, std::vector<Token>& out) {
  out.clear();
  if (max_bytes > 0 && line.size() > max_bytes) {
    return error_at(command_word(line), code::kTooLong,
                    "line of " + std::to_string(line.size()) + " bytes is longer than the limit of " +
                        std::to_string(max_bytes),
                    0);
  }
  for (std::size_t i = 0; i < line.size(); ++i) {
    const auto c = static_cast<unsigned char>(line[i]);
    if (!is_printable(c)) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "0x%02X", static_cast<unsigned>(c));
      return error_at(command_word(line), code::kBadByte,
                      std::string("byte ") + hex + " is not printable ASCII (0x20..0x7E)", i + 1);
    }
  }
  const std::string cmd = command_word(line);
  std::size_t i = 0;
  const std::size_t n = line.size();
  while (i < n) {
    while (i < n && line[i] == ' ') ++i;
    if (i >= n) break;
    Token tok;
    tok.column = i + 1;
    if (line[i] == '"') return error_at(cmd, code::kBadSyntax, "quoted text without a key (write key=\"...\")", i + 1);
    if (line[i] == '=') return error_at(cmd, code::kBadSyntax, "'=' without a key", i + 1);
    std::size_t j = i;
    while (j < n && line[j] != ' ' && line[j] != '=') ++j;
    if (j >= n || line[j] == ' ') {
      // A positional word.
      const std::string_view w = line.substr(i, j - i);
      if (w.find('"') != std::string_view::npos)
        return error_at(cmd, code::kBadSyntax, "stray '\"' in word '" + echo(w) + "'", i + 1 + w.find('"'));
      tok.positional = true;
      tok.value = std::string(w);
      tok.value_column = tok.column;
      out.push_back(std::move(tok));
      i = j;
      continue;
    }
    // key=value
    const std::string_view key = line.substr(i, j - i);
    for (std::size_t k = 0; k < key.size(); ++k) {
      if (!is_key_char(key[k]))
        return error_at(cmd, code::kBadSyntax, "bad character '" + std::string(1, key[k]) + "' in key '" + echo(key) + "'",
                        i + 1 + k);
    }
    tok.key = std::string(key);
    std::size_t v = j + 1;  // first byte of the value
    if (v < n && line[v] == '"') {
      tok.value_column = v + 2;
      std::size_t k = v + 1;
      bool closed = false;
      while (k < n) {
        const char c = line[k];
        if (c == '\\') {
          if (k + 1 >= n) break;
          const char e = line[k + 1];
          if (e != '"' && e != '\\')
            return error_at(cmd, code::kBadSyntax,
                            tok.key + "=: unknown escape '\\" + std::string(1, e) + "' (only \\\" and \\\\)", k + 1);
          tok.value += e;
          k += 2;
          continue;
        }
        if (c == '"') {
          closed = true;
          break;
        }
        tok.value += c;
        ++k;
      }
      if (!closed) return error_at(cmd, code::kBadSyntax, tok.key + "=: unterminated quoted value", v + 1);
      ++k;  // past the closing quote
      if (k < n && line[k] != ' ')
        return error_at(cmd, code::kBadSyntax, tok.key + "=: text after the closing quote", k + 1);
      i = k;
    } else {
      tok.value_column = v + 1;
      std::size_t k = v;
      while (k < n && line[k] != ' ') {
        if (line[k] == '"')
          return error_at(cmd, code::kBadSyntax, tok.key + "=: '\"' inside an unquoted value", k + 1);
        ++k;
      }
      if (k == v)
        return error_at(cmd, code::kBadSyntax, tok.key + "=: empty value (write " + tok.key + "=\"\" for empty text)",
                        v + 1);
      tok.value = std::string(line.substr(v, k - v));
      i = k;
    }
    out.push_back(std::move(tok));
  }
  if (out.empty()) return error_at("?", code::kEmptyLine, "empty line", 0);
  return std::nullopt;
}

NumStatus parse_double(std::string_view s, double& out) {
  std::size_t i = 0;
  bool negative = false;
  if (i < s.size() && (s[i] == '+' || s[i] == '-')) {
    negative = s[i] == '-';
    ++i;
  }
  const std::string_view body = s.substr(i);
  if (equals_lower(body, "nan") || equals_lower(body, "inf") || equals_lower(body, "infinity"))
    return NumStatus::kNotFinite;
  // Grammar check, and the decimal magnitude of the leading digit (to tell overflow from underflow).
  std::size_t int_digits = 0, frac_digits = 0;
  long lead = 0;  // decimal exponent of the first non-zero digit, before the e-part
  bool seen_nonzero = false;
  std::size_t k = i;
  while (k < s.size() && is_digit(s[k])) {
    if (s[k] != '0' && !seen_nonzero) seen_nonzero = true;
    if (seen_nonzero) ++lead;
    ++int_digits;
    ++k;
  }
  if (seen_nonzero) lead -= 1;
  if (k < s.size() && s[k] == '.') {
    ++k;
    long zeros = 0;
    while (k < s.size() && is_digit(s[k])) {
      if (!seen_nonzero) {
        if (s[k] == '0') {
          ++zeros;
        } else {
          seen_nonzero = true;
          lead = -(zeros + 1);
        }
      }
      ++frac_digits;
      ++k;
    }
  }
  if (int_digits + frac_digits == 0) return NumStatus::kBad;
  long exp10 = 0;
  if (k < s.size() && (s[k] == 'e' || s[k] == 'E')) {
    ++k;
    bool exp_negative = false;
    if (k < s.size() && (s[k] == '+' || s[k] == '-')) {
      exp_negative = s[k] == '-';
      ++k;
    }
    std::size_t exp_digits = 0;
    while (k < s.size() && is_digit(s[k])) {
      if (exp10 < 1000000) exp10 = exp10 * 10 + (s[k] - '0');
      ++exp_digits;
      ++k;
    }
    if (exp_digits == 0) return NumStatus::kBad;
    if (exp_negative) exp10 = -exp10;
  }
  if (k != s.size()) return NumStatus::kBad;
  double v = 0.0;
  const char* first = s.data() + i;
  const char* last = s.data() + s.size();
  const auto r = std::from_chars(first, last, v, std::chars_format::general);
  if (r.ec == std::errc::result_out_of_range) {
    if (seen_nonzero && lead + exp10 > 0) return NumStatus::kNotFinite;  // overflow
    v = 0.0;  // underflow below the smallest subnormal
  } else if (r.ec != std::errc() || r.ptr != last) {
    return NumStatus::kBad;
  }
  out = negative ? -v : v;
  return NumStatus::kOk;
}

bool parse_uint(std::string_view s, std::uint64_t& out) {
  if (s.empty()) return false;
  for (char c : s)
    if (!is_digit(c)) return false;
  std::uint64_t v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size()) return false;
  out = v;
  return true;
}

// ------------------------------------------------------------------------------------------------
// Args

void Args::fail(std::string_view code, std::string message, std::size_t column) {
  if (error_) return;
  error_ = error_at(command_, code, std::move(message), column);
}

void Args::check_keys(std::initializer_list<std::string_view> allowed, std::size_t positionals, bool ignore_unknown) {
  std::size_t seen_positional = 0;
  for (std::size_t i = 0; i < tokens_.size() && ok(); ++i) {
    const Token& t = tokens_[i];
    if (t.positional) {
      if (++seen_positional > positionals)
        fail(code::kBadSyntax, "unexpected word '" + echo(t.value) + "' (arguments are key=value)", t.column);
      continue;
    }
    bool known = false;
    for (std::string_view a : allowed) known = known || (a == t.key);
    if (!known && ignore_unknown) continue;
    if (known) {
      // Only known keys are compared, so this stays linear in the number of words.
      for (std::size_t j = 0; j < i; ++j) {
        if (!tokens_[j].positional && tokens_[j].key == t.key) {
          fail(code::kDuplicateArgument, t.key + "= given twice", t.column);
          break;
        }
      }
      continue;
    }
    std::string list;
    for (std::string_view a : allowed) list.append(list.empty() ? "" : " ").append(a).append("=");
    fail(code::kUnknownArgument,
         "unknown argument '" + echo(t.key) + "=' for " + command_ + (list.empty() ? " (takes none)" : " (takes " + list + ")"),
         t.column);
  }
}

void Args::require(std::initializer_list<std::string_view> keys) {
  for (std::string_view k : keys) {
    if (!ok()) return;
    if (!has(k)) fail(code::kMissingArgument, "missing argument " + std::string(k) + "=", 0);
  }
}

const Token* Args::find(std::string_view key) const {
  for (const Token& t : tokens_)
    if (!t.positional && t.key == key) return &t;
  return nullptr;
}

std::vector<const Token*> Args::positional() const {
  std::vector<const Token*> p;
  for (const Token& t : tokens_)
    if (t.positional) p.push_back(&t);
  return p;
}

const Token* Args::need(std::string_view key) {
  if (!ok()) return nullptr;
  const Token* t = find(key);
  if (t == nullptr) fail(code::kMissingArgument, "missing argument " + std::string(key) + "=", 0);
  return t;
}

std::string Args::name(std::string_view key) {
  const Token* t = need(key);
  if (t == nullptr) return {};
  if (!is_valid_name(t->value)) {
    fail(code::kBadName,
         std::string(key) + "=: '" + echo(t->value) + "' is not a valid name ([A-Za-z0-9_.-], 1 to " +
             std::to_string(kMaxNameBytes) + " characters)",
         t->value_column);
    return {};
  }
  return t->value;
}

std::string Args::text(std::string_view key) {
  const Token* t = need(key);
  if (t == nullptr) return {};
  if (t->value.empty()) {
    fail(code::kBadArgument, std::string(key) + "=: must not be empty", t->value_column);
    return {};
  }
  return t->value;
}

bool Args::read_number(std::string_view text, std::string_view key, std::size_t column, std::string_view what,
                       double& out) {
  const std::string where = std::string(key) + "=: " + (what.empty() ? "" : std::string(what) + " ");
  if (text.empty()) {
    fail(code::kBadNumber, where + "is empty", column);
    return false;
  }
  switch (parse_double(text, out)) {
    case NumStatus::kOk:
      return true;
    case NumStatus::kNotFinite:
      fail(code::kNotFinite, where + "'" + echo(text) + "' is not a finite number", column);
      return false;
    case NumStatus::kBad:
      break;
  }
  fail(code::kBadNumber, where + "'" + echo(text) + "' is not a number", column);
  return false;
}

double Args::number(std::string_view key) {
  const Token* t = need(key);
  double v = 0.0;
  if (t != nullptr) read_number(t->value, key, t->value_column, {}, v);
  return ok() ? v : 0.0;
}

std::uint64_t Args::whole(std::string_view key) {
  const Token* t = need(key);
  if (t == nullptr) return 0;
  std::uint64_t v = 0;
  if (!parse_uint(t->value, v)) {
    bool digits = !t->value.empty();
    for (char c : t->value) digits = digits && is_digit(c);
    fail(code::kBadNumber,
         std::string(key) + "=: '" + echo(t->value) + "' " +
             (digits ? "does not fit in 64 bits" : "is not a whole number (digits only)"),
         t->value_column);
    return 0;
  }
  return v;
}

std::size_t Args::word(std::string_view key, std::initializer_list<std::string_view> words) {
  const Token* t = need(key);
  if (t == nullptr) return 0;
  std::size_t i = 0;
  std::string list;
  for (std::string_view w : words) {
    if (w == t->value) return i;
    list.append(list.empty() ? "" : "|").append(w);
    ++i;
  }
  fail(code::kBadArgument, std::string(key) + "=: '" + echo(t->value) + "' is not one of " + list, t->value_column);
  return 0;
}

}  // namespace v4r::protocol::detail
