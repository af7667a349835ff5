// v4r - robust model-based object tracking. MIT licence.
//
// Reader for ViSP `.cao` models (version V1). The file is read line by line: `#` starts a
// comment (outside double quotes), each non-empty line is one record (a count, a point, a line,
// a face, a cylinder, a circle or a load(...) statement). Sections come in a fixed order:
//   [V1] load(...)* points lines faces-from-lines faces-from-points [cylinders [circles]]
// Every error names the file, the 1-based line and the 1-based column of the offending token.
#include "v4r/model/cao_reader.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <fmt/format.h>

#include "v4r/core/log.hpp"

namespace v4r::model {
namespace {

namespace fs = std::filesystem;

constexpr double kPlanarityTolAbs = 1e-4;   ///< metres: a face point may lie this far off its plane silently
constexpr double kPlanarityTolRel = 1e-3;   ///< ... or this fraction of the face diameter, if larger
constexpr double kMinLength = 1e-9;         ///< metres: shorter edges, axes and radii are degenerate
constexpr double kMinSinCollinear = 1e-9;   ///< |sin(angle)| below which circle points are collinear
constexpr long long kMaxCount = 100'000'000;  ///< largest count a section may announce
constexpr int kMaxIncludeDepth = 64;        ///< nesting limit for load(...) statements

/// A whitespace-separated token of a line; `column` is 1-based (bytes).
struct Token {
  std::string_view text;
  int column = 0;
};

/// A line of the file with its comment removed and split into tokens.
struct TextLine {
  int number = 0;            ///< 1-based
  std::string_view content;  ///< the line without comment and line break; column = index + 1
  std::vector<Token> tokens;
};

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

/// Splits into tokens; double quotes group characters (so `name="a b"` is one token).
std::vector<Token> tokenize(std::string_view s) {
  std::vector<Token> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_space(s[i])) ++i;
    if (i >= s.size()) break;
    const std::size_t start = i;
    bool quoted = false;
    while (i < s.size() && (quoted || !is_space(s[i]))) {
      if (s[i] == '"') quoted = !quoted;
      ++i;
    }
    out.push_back(Token{s.substr(start, i - start), static_cast<int>(start) + 1});
  }
  return out;
}

/// Cuts the text into lines (LF, CRLF or lone CR), strips `#` comments outside quotes.
/// Also returns the position just past the last character (for end-of-file errors).
std::vector<TextLine> split_lines(std::string_view text, int& eof_line, int& eof_column) {
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);  // UTF-8 byte-order mark
  std::vector<TextLine> lines;
  std::size_t pos = 0;
  int number = 0;
  while (true) {
    ++number;
    std::size_t end = pos;
    while (end < text.size() && text[end] != '\n' && text[end] != '\r') ++end;
    std::string_view raw = text.substr(pos, end - pos);
    bool quoted = false;
    for (std::size_t i = 0; i < raw.size(); ++i) {
      if (raw[i] == '"') quoted = !quoted;
      if (raw[i] == '#' && !quoted) {
        raw = raw.substr(0, i);
        break;
      }
    }
    TextLine line;
    line.number = number;
    line.content = raw;
    line.tokens = tokenize(raw);
    if (!line.tokens.empty()) lines.push_back(std::move(line));
    if (end >= text.size()) {
      eof_line = number;
      eof_column = static_cast<int>(end - pos) + 1;
      break;
    }
    pos = end + 1;
    if (text[end] == '\r' && pos < text.size() && text[pos] == '\n') ++pos;
  }
  return lines;
}

enum class NumError { kNone, kNotNumber, kNotFinite, kOutOfRange };

/// Parses a whole token as a double (a leading '+' is allowed); never throws.
NumError to_double(std::string_view s, double& v) {
  const bool plus = !s.empty() && s.front() == '+';
  if (plus) s.remove_prefix(1);
  if (s.empty() || s.front() == '+' || (plus && s.front() == '-')) return NumError::kNotNumber;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ptr != s.data() + s.size()) return NumError::kNotNumber;
  if (ec == std::errc::result_out_of_range) return NumError::kOutOfRange;
  if (ec != std::errc()) return NumError::kNotNumber;
  if (!std::isfinite(v)) return NumError::kNotFinite;
  return NumError::kNone;
}

/// Parses a whole token as a decimal integer (a leading '+' is allowed); never throws.
NumError to_integer(std::string_view s, long long& v) {
  const bool plus = !s.empty() && s.front() == '+';
  if (plus) s.remove_prefix(1);
  if (s.empty() || s.front() == '+' || (plus && s.front() == '-')) return NumError::kNotNumber;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ptr != s.data() + s.size()) return NumError::kNotNumber;
  if (ec == std::errc::result_out_of_range) return NumError::kOutOfRange;
  if (ec != std::errc()) return NumError::kNotNumber;
  return NumError::kNone;
}

bool is_identifier(std::string_view s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  return std::all_of(s.begin(), s.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

/// Rotation matrix of the rotation vector theta*u (radians).
Eigen::Matrix3d rotation_from_tu(const Eigen::Vector3d& tu) {
  const double theta = tu.norm();
  if (theta < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(theta, tu / theta).toRotationMatrix();
}

std::optional<std::string> read_text_file(const fs::path& p) {
  std::error_code ec;
  if (!fs::is_regular_file(p, ec)) return std::nullopt;
  std::ifstream in(p, std::ios::binary);
  if (!in) return std::nullopt;
  std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return std::nullopt;
  return s;
}

/// Identity of a file for cycle detection.
std::string file_key(const fs::path& p) {
  std::error_code ec;
  fs::path c = fs::weakly_canonical(p, ec);
  if (ec) c = fs::absolute(p, ec).lexically_normal();
  return c.string();
}

/// The sections of a .cao file, in order.
enum class Section { kPoints, kLines, kFacesFromLines, kFacesFromPoints, kCylinders, kCircles };

struct SectionInfo {
  const char* plural;    ///< "points"
  const char* singular;  ///< "point"
};

SectionInfo info(Section s) {
  switch (s) {
    case Section::kPoints: return {"points", "point"};
    case Section::kLines: return {"lines", "line"};
    case Section::kFacesFromLines: return {"faces from lines", "face"};
    case Section::kFacesFromPoints: return {"faces from points", "face"};
    case Section::kCylinders: return {"cylinders", "cylinder"};
    case Section::kCircles: return {"circles", "circle"};
  }
  return {"?", "?"};
}

/// Parses one .cao text into a shared ModelBuilder, placing its features with T_root_file.
class CaoFileParser {
 public:
  CaoFileParser(ModelBuilder& builder, std::string source, std::string_view text, const Eigen::Isometry3d& T_root_file,
                std::vector<std::string> chain_keys, std::vector<std::string> chain_names, const CaoReadOptions& options,
                std::vector<Error>* warnings)
      : b_(builder),
        options_(options),
        warnings_(warnings),
        source_(std::move(source)),
        T_(T_root_file),
        chain_keys_(std::move(chain_keys)),
        chain_names_(std::move(chain_names)) {
    lines_ = split_lines(text, eof_line_, eof_column_);
  }

  Expected<void> run() {
    if (auto r = parse_header_and_loads(); !r) return r;
    long long prev_count = -1;
    std::optional<Section> prev;
    for (Section s : {Section::kPoints, Section::kLines, Section::kFacesFromLines, Section::kFacesFromPoints,
                      Section::kCylinders, Section::kCircles}) {
      const bool optional = s == Section::kCylinders || s == Section::kCircles;
      auto count = parse_count(s, prev, prev_count, optional);
      if (!count) return count.error();
      for (long long i = 0; i < *count; ++i) {
        auto r = parse_record(s, i, *count);
        if (!r) return r;
      }
      prev = s;
      prev_count = *count;
    }
    if (const TextLine* l = peek()) {
      return error(*l, l->tokens.front().column,
                   fmt::format("unexpected '{}' after the last section (3D circles, {} announced)",
                               l->tokens.front().text, prev_count));
    }
    return {};
  }

 private:
  // ---- record access --------------------------------------------------------------------------
  const TextLine* peek() const { return next_ < lines_.size() ? &lines_[next_] : nullptr; }
  const TextLine* take() { return next_ < lines_.size() ? &lines_[next_++] : nullptr; }

  Error error(int line, int column, std::string message) const {
    return Error{std::move(message), source_, line, column, {}};
  }
  Error error(const TextLine& l, int column, std::string message) const {
    return error(l.number, column, std::move(message));
  }
  Error eof_error(std::string message) const { return error(eof_line_, eof_column_, std::move(message)); }
  static int end_column(const TextLine& l) {
    const Token& t = l.tokens.back();
    return t.column + static_cast<int>(t.text.size());
  }

  // ---- numbers --------------------------------------------------------------------------------
  Expected<double> number(const TextLine& l, const Token& t, std::string_view what) const {
    double v = 0.0;
    switch (to_double(t.text, v)) {
      case NumError::kNone: return v;
      case NumError::kNotFinite:
        return error(l, t.column, fmt::format("{} must be a finite number, found '{}'", what, t.text));
      case NumError::kOutOfRange:
        return error(l, t.column, fmt::format("{} '{}' is out of range", what, t.text));
      case NumError::kNotNumber: break;
    }
    return error(l, t.column, fmt::format("expected a number for {}, found '{}'", what, t.text));
  }

  /// An index into a table of `size` entries named `what` ("point", "line").
  Expected<std::size_t> index(const TextLine& l, const Token& t, std::size_t size, std::string_view what) const {
    long long v = 0;
    const NumError e = to_integer(t.text, v);
    if (e == NumError::kNotNumber)
      return error(l, t.column, fmt::format("expected a {} index (an integer), found '{}'", what, t.text));
    if (e != NumError::kNone || v < 0 || static_cast<unsigned long long>(v) >= size) {
      const std::string range = size == 0 ? fmt::format("this file defines no {}s", what)
                                          : fmt::format("this file defines {} {}s, 0..{}", size, what, size - 1);
      return error(l, t.column, fmt::format("{} index {} is out of range ({})", what, t.text, range));
    }
    return static_cast<std::size_t>(v);
  }

  static bool is_integer_token(const Token& t) {
    long long v = 0;
    return to_integer(t.text, v) == NumError::kNone;
  }

  // ---- attributes -----------------------------------------------------------------------------
  /// Parses "R,G,B" (three numbers in [0, 1]) starting at `column`; an error points at the
  /// component at fault.
  Expected<Eigen::Vector3f> colour_value(const TextLine& l, int column, std::string_view key, std::string_view value) const {
    Eigen::Vector3f rgb;
    std::size_t start = 0;
    for (int c = 0; c < 3; ++c) {
      const std::size_t comma = value.find(',', start);
      const bool last = c == 2;
      if (!last && comma == std::string_view::npos)
        return error(l, column, fmt::format("{} needs 3 values R,G,B in 0..1 (e.g. {}=0.2,0.6,0.1), found '{}'", key, key, value));
      if (last && comma != std::string_view::npos)
        return error(l, column + static_cast<int>(comma), fmt::format("{} needs 3 values R,G,B, found more in '{}'", key, value));
      const std::string_view part = value.substr(start, last ? std::string_view::npos : comma - start);
      double v = 0.0;
      if (to_double(part, v) != NumError::kNone || !(v >= 0.0 && v <= 1.0))
        return error(l, column + static_cast<int>(start),
                     fmt::format("{}: component {} must be a number in 0..1, found '{}'", key, "RGB"[c], part));
      rgb[c] = static_cast<float>(v);
      start = comma + 1;
    }
    return rgb;
  }

  /// Parses tokens[first..] as key=value attributes; `entry` names the record for messages.
  Expected<Attributes> attributes(const TextLine& l, std::size_t first, std::string_view entry) const {
    Attributes attr;
    for (std::size_t k = first; k < l.tokens.size(); ++k) {
      const Token& t = l.tokens[k];
      const std::size_t eq = t.text.find('=');
      if (eq == std::string_view::npos) {
        double dummy = 0.0;
        if (to_double(t.text, dummy) != NumError::kNotNumber)
          return error(l, t.column, fmt::format("unexpected extra value '{}' after the {}", t.text, entry));
        return error(l, t.column, fmt::format("malformed attribute '{}': expected key=value (e.g. name=lid)", t.text));
      }
      const std::string_view key = t.text.substr(0, eq);
      std::string_view value = t.text.substr(eq + 1);
      if (!is_identifier(key))
        return error(l, t.column, fmt::format("malformed attribute '{}': the key must be a name (e.g. name=lid)", t.text));
      const int value_column = t.column + static_cast<int>(eq) + 1;
      if (!value.empty() && value.front() == '"') {
        if (value.size() < 2 || value.back() != '"')
          return error(l, value_column, fmt::format("attribute '{}': unterminated quoted value", key));
        value = value.substr(1, value.size() - 2);
      }
      if (value.find('"') != std::string_view::npos)
        return error(l, value_column, fmt::format("attribute '{}': stray '\"' in the value", key));
      if (value.empty()) return error(l, value_column, fmt::format("attribute '{}' has no value", key));
      if (key == "name") {
        attr.name = std::string(value);
      } else if (key == "colour" || key == "color") {
        auto c = colour_value(l, value_column, key, value);
        if (!c) return c.error();
        attr.colour = *c;
      } else if (key == "useLod") {
        if (value != "true" && value != "false" && value != "1" && value != "0")
          return error(l, value_column, fmt::format("useLod must be true or false, found '{}'", value));
      } else if (key == "minLineLengthThreshold" || key == "minPolygonAreaThreshold") {
        double v = 0.0;
        if (to_double(value, v) != NumError::kNone || v < 0.0)
          return error(l, value_column, fmt::format("{} must be a finite number >= 0, found '{}'", key, value));
      }
      // Other well-formed keys are accepted and ignored (ViSP tracker settings).
    }
    return attr;
  }

  // ---- header and includes --------------------------------------------------------------------
  static bool is_load(const TextLine& l) {
    const std::string_view t = l.tokens.front().text;
    if (t.substr(0, 4) != "load") return false;
    if (t.size() > 4) return t[4] == '(';
    return l.tokens.size() > 1 && l.tokens[1].text.front() == '(';
  }

  Expected<void> parse_header_and_loads() {
    if (const TextLine* l = peek(); l && l->tokens.size() == 1 && l->tokens[0].text.size() >= 2 &&
                                    (l->tokens[0].text[0] == 'V' || l->tokens[0].text[0] == 'v')) {
      long long version = 0;
      if (to_integer(l->tokens[0].text.substr(1), version) == NumError::kNone) {
        if (version != 1)
          return error(*l, l->tokens[0].column,
                       fmt::format("unsupported .cao version '{}' (only V1 is supported)", l->tokens[0].text));
        take();
      }
    }
    while (const TextLine* l = peek()) {
      if (!is_load(*l)) break;
      take();
      if (auto r = parse_load(*l); !r) return r;
    }
    return {};
  }

  /// load("path", t=[x, y, z], tu=[ux, uy, uz]) -- t in metres, tu = theta*u in radians.
  Expected<void> parse_load(const TextLine& l) {
    const std::string_view s = l.content;
    std::size_t i = 0;
    auto col = [](std::size_t pos) { return static_cast<int>(pos) + 1; };
    auto skip_ws = [&] {
      while (i < s.size() && is_space(s[i])) ++i;
    };
    skip_ws();
    const int load_column = col(i);
    i += 4;  // "load"
    skip_ws();
    if (i >= s.size() || s[i] != '(') return error(l, col(i), "expected '(' after load");
    ++i;
    auto unterminated = [&] {
      return error(l, col(s.size()),
                   fmt::format("unterminated load(...): expected ')' to close the '(' at column {}", load_column + 4));
    };
    skip_ws();
    if (i >= s.size()) return unterminated();
    if (s[i] != '"') return error(l, col(i), "expected a quoted file name in load(...), e.g. load(\"part.cao\")");
    const std::size_t close = s.find('"', i + 1);
    if (close == std::string_view::npos) return error(l, col(i), "unterminated file name in load(...)");
    const std::string_view given = s.substr(i + 1, close - i - 1);
    if (given.empty()) return error(l, col(i), "empty file name in load(...)");
    i = close + 1;

    Eigen::Vector3d t = Eigen::Vector3d::Zero(), tu = Eigen::Vector3d::Zero();
    bool have_t = false, have_tu = false;
    while (true) {
      skip_ws();
      if (i >= s.size()) return unterminated();
      if (s[i] == ')') {
        ++i;
        break;
      }
      if (s[i] == ',') {
        ++i;
        skip_ws();
        if (i >= s.size()) return unterminated();
      }
      const std::size_t key_start = i;
      while (i < s.size() && (std::isalnum(static_cast<unsigned char>(s[i])) || s[i] == '_')) ++i;
      const std::string_view key = s.substr(key_start, i - key_start);
      if (key != "t" && key != "tu") {
        if (key.empty()) return error(l, col(key_start), fmt::format("unexpected '{}' in load(...)", s[key_start]));
        return error(l, col(key_start), fmt::format("unknown load parameter '{}' (expected t= or tu=)", key));
      }
      bool& seen = key == "t" ? have_t : have_tu;
      if (seen) return error(l, col(key_start), fmt::format("load parameter '{}' given twice", key));
      seen = true;
      skip_ws();
      if (i >= s.size()) return unterminated();
      if (s[i] != '=') return error(l, col(i), fmt::format("expected '=' after '{}' in load(...)", key));
      ++i;
      skip_ws();
      if (i >= s.size()) return unterminated();
      if (s[i] != '[') return error(l, col(i), fmt::format("expected '[' to start the 3 values of '{}'", key));
      ++i;
      Eigen::Vector3d& v = key == "t" ? t : tu;
      for (int k = 0; k < 3; ++k) {
        skip_ws();
        if (k > 0 && i < s.size() && s[i] == ',') {
          ++i;
          skip_ws();
        }
        if (i >= s.size()) return unterminated();
        const std::size_t ns = i;
        while (i < s.size() && !is_space(s[i]) && s[i] != ',' && s[i] != ']' && s[i] != ')') ++i;
        if (i == ns) return error(l, col(ns), fmt::format("'{}' needs 3 values, found {}", key, k));
        const Token tok{s.substr(ns, i - ns), col(ns)};
        auto x = number(l, tok, fmt::format("component {} of '{}'", k + 1, key));
        if (!x) return x.error();
        v[k] = *x;
      }
      skip_ws();
      if (i >= s.size()) return unterminated();
      if (s[i] != ']') return error(l, col(i), fmt::format("expected ']' after the 3 values of '{}'", key));
      ++i;
    }
    skip_ws();
    if (i < s.size()) return error(l, col(i), fmt::format("unexpected '{}' after load(...)", s.substr(i)));
    return include(l, load_column, given, t, tu);
  }

  Expected<void> include(const TextLine& l, int column, std::string_view given, const Eigen::Vector3d& t,
                         const Eigen::Vector3d& tu) {
    fs::path resolved = (fs::path(source_).parent_path() / fs::path(std::string(given))).lexically_normal();
    if (options_.include_check) {
      auto allowed = options_.include_check(resolved.string());
      if (!allowed) {
        Error e = error(l, column, fmt::format("load(\"{}\"): {}", given, allowed.error().message));
        e.field = allowed.error().field;
        return e;
      }
      resolved = *allowed;
    }
    const std::string name = resolved.string();
    const std::string key = file_key(resolved);
    if (std::find(chain_keys_.begin(), chain_keys_.end(), key) != chain_keys_.end()) {
      std::string chain;
      for (const std::string& n : chain_names_) chain += n + " -> ";
      return error(l, column, fmt::format("include cycle: {}{}", chain, name));
    }
    if (static_cast<int>(chain_keys_.size()) >= kMaxIncludeDepth)
      return error(l, column, fmt::format("includes nested deeper than {} levels", kMaxIncludeDepth));
    const std::optional<std::string> text = read_text_file(resolved);
    if (!text) return error(l, column, fmt::format("cannot open included file '{}' (resolved to '{}')", given, name));

    Eigen::Isometry3d T_file_child = Eigen::Isometry3d::Identity();
    T_file_child.linear() = rotation_from_tu(tu);
    T_file_child.translation() = t;
    std::vector<std::string> keys = chain_keys_, names = chain_names_;
    keys.push_back(key);
    names.push_back(name);
    CaoFileParser child(b_, name, *text, T_ * T_file_child, std::move(keys), std::move(names), options_, warnings_);
    if (auto r = child.run(); !r) {
      Error e = r.error();
      e.message += fmt::format(" [included from {}:{}]", source_, l.number);
      return e;
    }
    return {};
  }

  // ---- counts -----------------------------------------------------------------------------------
  Expected<long long> parse_count(Section s, std::optional<Section> prev, long long prev_count, bool optional) {
    const SectionInfo si = info(s);
    const TextLine* l = take();
    if (!l) {
      if (optional) return 0LL;
      return eof_error(fmt::format("unexpected end of file: expected the number of {}", si.plural));
    }
    if (is_load(*l))
      return error(*l, l->tokens.front().column, "load(...) is only allowed before the points section");
    const std::string hint =
        prev ? fmt::format(" (does the {} section hold more than the {} announced?)", info(*prev).plural, prev_count) : "";
    if (l->tokens.size() != 1)
      return error(*l, l->tokens[1].column,
                   fmt::format("expected the number of {} alone on this line, found {} values{}", si.plural,
                               l->tokens.size(), hint));
    const Token& t = l->tokens[0];
    long long n = 0;
    const NumError e = to_integer(t.text, n);
    if (e == NumError::kNotNumber)
      return error(*l, t.column, fmt::format("expected the number of {} (an integer), found '{}'{}", si.plural, t.text, hint));
    if (e != NumError::kNone || n > kMaxCount)
      return error(*l, t.column, fmt::format("the number of {} is too large: {}", si.plural, t.text));
    if (n < 0) return error(*l, t.column, fmt::format("the number of {} must be >= 0, found {}", si.plural, n));
    return n;
  }

  // ---- records ----------------------------------------------------------------------------------
  Expected<void> parse_record(Section s, long long i, long long n) {
    const SectionInfo si = info(s);
    const TextLine* l = take();
    if (!l)
      return eof_error(fmt::format("unexpected end of file: expected {} {}, found {}", n, si.plural, i));
    if (l->tokens.size() == 1 && is_integer_token(l->tokens[0]))
      return error(*l, l->tokens[0].column,
                   fmt::format("expected {} {}, found {} before this line (a lone integer here looks like the "
                               "count of the next section)",
                               n, si.plural, i));
    switch (s) {
      case Section::kPoints: return parse_point(*l, i, n);
      case Section::kLines: return parse_line(*l, i);
      case Section::kFacesFromLines: return parse_face_from_lines(*l, i);
      case Section::kFacesFromPoints: return parse_face_from_points(*l, i);
      case Section::kCylinders: return parse_cylinder(*l, i);
      case Section::kCircles: return parse_circle(*l, i);
    }
    return {};
  }

  /// Checks that `l` holds at least `k` leading values (not attributes) for `what`.
  Expected<void> need_values(const TextLine& l, std::size_t k, std::string_view what) const {
    for (std::size_t j = 0; j < k; ++j) {
      if (j >= l.tokens.size())
        return error(l, end_column(l), fmt::format("{} needs {} values, found {}", what, k, j));
      if (l.tokens[j].text.find('=') != std::string_view::npos)
        return error(l, l.tokens[j].column, fmt::format("{} needs {} values, found {}", what, k, j));
    }
    return {};
  }

  Expected<void> parse_point(const TextLine& l, long long i, long long n) {
    const std::string what = fmt::format("point {} (x y z)", i);
    if (auto r = need_values(l, 3, what); !r) return r;
    Eigen::Vector3d p;
    for (int k = 0; k < 3; ++k) {
      auto v = number(l, l.tokens[k], fmt::format("coordinate {} of point {}", "xyz"[k], i));
      if (!v) return v.error();
      p[k] = *v;
    }
    if (l.tokens.size() > 3)
      return error(l, l.tokens[3].column,
                   fmt::format("unexpected '{}' after the 3 coordinates of point {}", l.tokens[3].text, i));
    const Eigen::Vector3d q = T_ * p;
    points_.push_back(q);
    point_ids_.push_back(b_.add_junction(q));
    return {};
  }

  Expected<void> parse_line(const TextLine& l, long long i) {
    if (auto r = need_values(l, 2, fmt::format("line {} (two point indices)", i)); !r) return r;
    auto a = index(l, l.tokens[0], points_.size(), "point");
    if (!a) return a.error();
    auto b = index(l, l.tokens[1], points_.size(), "point");
    if (!b) return b.error();
    if ((points_[*a] - points_[*b]).norm() < kMinLength)
      return error(l, l.tokens[1].column,
                   fmt::format("line {} has zero length (points {} and {} coincide)", i, *a, *b));
    auto attr = attributes(l, 2, fmt::format("2 point indices of line {}", i));
    if (!attr) return attr.error();
    b_.add_line(point_ids_[*a], point_ids_[*b], std::move(*attr));
    line_ends_.emplace_back(*a, *b);
    return {};
  }

  /// Adds a face from local point indices; errors point at the record's first token and name
  /// this file's point indices.
  /// `point_columns` holds the column of each loop point's index token where the record lists
  /// points (faces from points), else is empty.
  Expected<void> add_face(const TextLine& l, long long i, const std::vector<std::size_t>& loop, Attributes attr,
                          const std::vector<int>& point_columns = {}) {
    const std::size_t n = loop.size();
    double diameter = 0.0;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t a = loop[k], c = loop[(k + 1) % n];
      if ((points_[a] - points_[c]).norm() < kMinLength)
        return error(l, l.tokens[0].column,
                     fmt::format("face {} is degenerate: consecutive points {} and {} coincide", i, a, c));
      for (std::size_t m : loop) diameter = std::max(diameter, (points_[a] - points_[m]).norm());
      centroid += points_[a];
    }
    centroid /= static_cast<double>(n);
    // Newell's normal about the centroid (twice the area times the unit normal).
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < n; ++k)
      normal += (points_[loop[k]] - centroid).cross(points_[loop[(k + 1) % n]] - centroid);
    if (normal.norm() <= 1e-9 * diameter * diameter)
      return error(l, l.tokens[0].column, fmt::format("face {} is degenerate: its points enclose no area", i));
    // Distances from the least-squares plane (the plane ModelBuilder::add_face gives the face).
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (std::size_t k : loop) scatter += (points_[k] - centroid) * (points_[k] - centroid).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
    const Eigen::Vector3d plane_n = eig.info() == Eigen::Success ? Eigen::Vector3d(eig.eigenvectors().col(0).normalized())
                                                                 : Eigen::Vector3d(normal.normalized());
    std::size_t worst = 0;  // position in the loop of the point farthest from the plane
    double worst_d = -1.0;
    for (std::size_t k = 0; k < n; ++k) {
      const double d = std::abs(plane_n.dot(points_[loop[k]] - centroid));
      if (d > worst_d) {
        worst_d = d;
        worst = k;
      }
    }
    const double silent_tol = std::max(kPlanarityTolAbs, kPlanarityTolRel * diameter);
    const double bound = std::max(silent_tol, options_.max_off_plane * diameter);
    const double percent = 100.0 * worst_d / diameter;
    if (worst_d > bound) {
      // Point at the worst point's index where the record lists points.
      const int column = point_columns.size() == n ? point_columns[worst] : l.tokens[0].column;
      return error(l, column,
                   fmt::format("face {} is not planar: point {} is {:.3g} m off the face's least-squares plane, "
                               "{:.3g} % of its {:.3g} m diameter (refused above {:.3g} %, the reader's "
                               "max_off_plane)",
                               i, loop[worst], worst_d, percent, diameter, 100.0 * options_.max_off_plane));
    }
    if (worst_d > silent_tol) {
      Error w = error(l, l.tokens[0].column,
                      fmt::format("face {} is not planar: point {} is {:.3g} m off the face's least-squares plane, "
                                  "{:.3g} % of its {:.3g} m diameter; accepted (refused above {:.3g} %)",
                                  i, loop[worst], worst_d, percent, diameter, 100.0 * options_.max_off_plane));
      if (warnings_ != nullptr) {
        warnings_->push_back(std::move(w));
      } else {
        V4R_LOG_WARN("{}", w.to_string());
      }
    }
    std::vector<Index> ids;
    ids.reserve(n);
    for (std::size_t k : loop) ids.push_back(point_ids_[k]);
    auto r = b_.add_face(ids, std::move(attr), std::max(bound, worst_d) * 1.01 + 1e-12);
    if (!r) return error(l, l.tokens[0].column, fmt::format("face {}: {}", i, r.error().message));
    return {};
  }

  /// Reads "n i1 ... in [attributes]" with n >= 3 distinct indices below `size`.
  Expected<std::vector<std::size_t>> index_list(const TextLine& l, long long i, std::size_t size,
                                                std::string_view what) const {
    const Token& t0 = l.tokens[0];
    long long n = 0;
    const NumError e = to_integer(t0.text, n);
    if (e == NumError::kNotNumber)
      return error(l, t0.column, fmt::format("face {}: expected the number of {}s (an integer), found '{}'", i, what, t0.text));
    if (e != NumError::kNone)
      return error(l, t0.column, fmt::format("face {}: the number of {}s is too large: {}", i, what, t0.text));
    if (n < 3) return error(l, t0.column, fmt::format("face {}: a face needs at least 3 {}s, found {}", i, what, n));
    std::vector<std::size_t> out;
    for (long long k = 0; k < n; ++k) {
      const std::size_t j = static_cast<std::size_t>(k) + 1;
      if (j >= l.tokens.size() || l.tokens[j].text.find('=') != std::string_view::npos) {
        const int c = j >= l.tokens.size() ? end_column(l) : l.tokens[j].column;
        return error(l, c, fmt::format("face {} announces {} {}s but lists {}", i, n, what, k));
      }
      auto idx = index(l, l.tokens[j], size, what);
      if (!idx) return idx.error();
      if (std::find(out.begin(), out.end(), *idx) != out.end())
        return error(l, l.tokens[j].column, fmt::format("face {} lists {} {} twice", i, what, *idx));
      out.push_back(*idx);
    }
    return out;
  }

  Expected<void> parse_face_from_points(const TextLine& l, long long i) {
    auto loop = index_list(l, i, points_.size(), "point");
    if (!loop) return loop.error();
    auto attr = attributes(l, loop->size() + 1, fmt::format("{} point indices of face {}", loop->size(), i));
    if (!attr) return attr.error();
    std::vector<int> columns;
    for (std::size_t k = 0; k < loop->size(); ++k) columns.push_back(l.tokens[k + 1].column);
    return add_face(l, i, *loop, std::move(*attr), columns);
  }

  Expected<void> parse_face_from_lines(const TextLine& l, long long i) {
    auto ls = index_list(l, i, line_ends_.size(), "line");
    if (!ls) return ls.error();
    auto attr = attributes(l, ls->size() + 1, fmt::format("{} line indices of face {}", ls->size(), i));
    if (!attr) return attr.error();
    // Every point of a closed loop is shared by exactly two of its lines.
    const std::vector<std::size_t>& L = *ls;
    auto other_line_at = [&](std::size_t p, std::size_t exclude) -> std::optional<std::size_t> {
      for (std::size_t k = 0; k < L.size(); ++k) {
        if (k == exclude) continue;
        const auto [a, b] = line_ends_[L[k]];
        if (a == p || b == p) return k;
      }
      return std::nullopt;
    };
    for (std::size_t k = 0; k < L.size(); ++k) {
      for (std::size_t p : {line_ends_[L[k]].first, line_ends_[L[k]].second}) {
        int uses = 0;
        for (std::size_t m : L) uses += (line_ends_[m].first == p) + (line_ends_[m].second == p);
        if (uses != 2)
          return error(l, l.tokens[k + 1].column,
                       fmt::format("face {}: its lines do not form one closed loop (point {} ends {} of them)", i, p,
                                   uses));
      }
    }
    // Walk in the listed order: orient line 0 towards line 1 when they touch.
    auto [start, at] = line_ends_[L[0]];
    const auto [a1, b1] = line_ends_[L[1]];
    if (start == a1 || start == b1) std::swap(start, at);
    std::vector<std::size_t> loop{start};
    std::vector<bool> used(L.size(), false);
    used[0] = true;
    std::size_t current = 0;
    while (at != start) {
      loop.push_back(at);
      const auto next = other_line_at(at, current);
      if (!next || used[*next]) break;
      used[*next] = true;
      current = *next;
      const auto [a, b] = line_ends_[L[current]];
      at = a == at ? b : a;
    }
    if (std::count(used.begin(), used.end(), true) != static_cast<long>(L.size()))
      return error(l, l.tokens[0].column, fmt::format("face {}: its lines form several loops, not one", i));
    return add_face(l, i, loop, std::move(*attr));
  }

  Expected<void> parse_cylinder(const TextLine& l, long long i) {
    if (auto r = need_values(l, 3, fmt::format("cylinder {} (2 axis point indices and a radius)", i)); !r) return r;
    auto a = index(l, l.tokens[0], points_.size(), "point");
    if (!a) return a.error();
    auto b = index(l, l.tokens[1], points_.size(), "point");
    if (!b) return b.error();
    if ((points_[*a] - points_[*b]).norm() < kMinLength)
      return error(l, l.tokens[1].column,
                   fmt::format("cylinder {} has a zero-length axis (points {} and {} coincide)", i, *a, *b));
    auto r = number(l, l.tokens[2], fmt::format("the radius of cylinder {}", i));
    if (!r) return r.error();
    if (!(*r >= kMinLength))
      return error(l, l.tokens[2].column, fmt::format("the radius of cylinder {} must be > 0, found {}", i, l.tokens[2].text));
    auto attr = attributes(l, 3, fmt::format("radius of cylinder {}", i));
    if (!attr) return attr.error();
    Cylinder c;
    c.p1 = points_[*a];
    c.p2 = points_[*b];
    c.radius = *r;
    c.attr = std::move(*attr);
    b_.add_cylinder(c);
    return {};
  }

  Expected<void> parse_circle(const TextLine& l, long long i) {
    if (auto r = need_values(l, 4, fmt::format("circle {} (radius, centre and 2 plane point indices)", i)); !r) return r;
    auto r = number(l, l.tokens[0], fmt::format("the radius of circle {}", i));
    if (!r) return r.error();
    if (!(*r >= kMinLength))
      return error(l, l.tokens[0].column, fmt::format("the radius of circle {} must be > 0, found {}", i, l.tokens[0].text));
    std::size_t idx[3];
    for (int k = 0; k < 3; ++k) {
      auto v = index(l, l.tokens[k + 1], points_.size(), "point");
      if (!v) return v.error();
      idx[k] = *v;
    }
    const Eigen::Vector3d c = points_[idx[0]];
    const Eigen::Vector3d u = points_[idx[1]] - c, v = points_[idx[2]] - c;
    const Eigen::Vector3d n = u.cross(v);
    if (u.norm() < kMinLength || v.norm() < kMinLength || n.norm() < kMinSinCollinear * u.norm() * v.norm())
      return error(l, l.tokens[1].column,
                   fmt::format("circle {}: points {}, {} and {} are collinear, so they define no plane", i, idx[0],
                               idx[1], idx[2]));
    auto attr = attributes(l, 4, fmt::format("4 values of circle {}", i));
    if (!attr) return attr.error();
    CircleArc arc;
    arc.center = c;
    arc.normal = n.normalized();
    arc.x_axis = u.normalized();
    arc.radius = *r;
    arc.attr = std::move(*attr);
    b_.add_arc(std::move(arc));
    return {};
  }

  ModelBuilder& b_;
  const CaoReadOptions& options_;
  std::vector<Error>* warnings_;  ///< accepted imperfections, or nullptr
  std::string source_;
  Eigen::Isometry3d T_;  ///< T_root_file: places this file's points in the root model frame
  std::vector<std::string> chain_keys_, chain_names_;  ///< files being parsed, root first (this one last)
  std::vector<TextLine> lines_;  ///< non-empty lines only
  std::size_t next_ = 0;
  int eof_line_ = 1, eof_column_ = 1;
  std::vector<Eigen::Vector3d> points_;  ///< this file's points, in the root frame
  std::vector<Index> point_ids_;         ///< junction index of each of this file's points
  std::vector<std::pair<std::size_t, std::size_t>> line_ends_;  ///< this file's lines (local point indices)
};

}  // namespace

Expected<Model> parse_cao(const std::string& text, const std::string& source, const CaoReadOptions& options,
                          std::vector<Error>* warnings) {
  if (!(options.max_off_plane >= 0.0 && options.max_off_plane <= 1.0))
    return Error{fmt::format("reader option max_off_plane must be in [0, 1] (fraction of a face's diameter), got {}",
                             options.max_off_plane),
                 source, 0, 0, "max_off_plane"};
  ModelBuilder builder(fs::path(source).stem().string());
  CaoFileParser parser(builder, source, text, Eigen::Isometry3d::Identity(), {file_key(source)}, {source}, options,
                       warnings);
  if (auto r = parser.run(); !r) return r.error();
  auto model = std::move(builder).build();
  if (!model) {
    Error e = model.error();
    e.file = source;
    return e;
  }
  return model;
}

Expected<Model> load_cao(const std::string& path, const CaoReadOptions& options, std::vector<Error>* warnings) {
  const std::optional<std::string> text = read_text_file(path);
  if (!text) return Error{"cannot open file", path, 0, 0, {}};
  return parse_cao(*text, path, options, warnings);
}

}  // namespace v4r::model
