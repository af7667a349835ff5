// v4r - robust model-based object tracking. MIT licence.
//
// Calibration files: OpenCV FileStorage YAML and ROS camera_info YAML (file and message forms),
// read with yaml-cpp after two line-preserving rewrites (the `%YAML:1.0` directive, which is not
// valid YAML 1.2, and the `!!opencv-matrix` tags). Every failure becomes an Error with the file,
// the 1-based line and column of the offending node and the key; nothing here throws.

#include "v4r/io/camera_io.hpp"

#include <cctype>

#include "camera_xml.hpp"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <exception>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <sstream>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

namespace v4r::io {
namespace {

/// Number of distortion coefficients v4r models (k1 k2 p1 p2 k3).
constexpr std::size_t kModelledCoefficients = 5;
/// Fewest coefficients accepted (k1 k2 p1 p2; k3 is then zero).
constexpr std::size_t kMinCoefficients = 4;
/// Relative tolerance on the structural zeros and the one of a camera matrix.
constexpr double kStructureTolerance = 1e-9;
/// Largest accepted image side, pixels (catches swapped or garbage values).
constexpr double kMaxImageSide = 1'000'000.0;

enum class NumberStatus { kOk, kNotNumber, kNotFinite };

/// Parses all of `s` as a double, locale-independently; YAML's .nan/.inf count as not finite.
NumberStatus parse_number(std::string_view s, double& out) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  if (s.empty()) return NumberStatus::kNotNumber;
  std::string_view body = s;
  if (body.front() == '+' || body.front() == '-') body.remove_prefix(1);
  if (body == ".nan" || body == ".NaN" || body == ".NAN" || body == ".inf" || body == ".Inf" || body == ".INF") {
    return NumberStatus::kNotFinite;
  }
  if (s.front() == '+') s.remove_prefix(1);
  const char* end = s.data() + s.size();
  const auto [ptr, ec] = std::from_chars(s.data(), end, out);
  if (ec == std::errc::result_out_of_range) return NumberStatus::kNotFinite;
  if (ec != std::errc() || ptr != end) return NumberStatus::kNotNumber;
  return std::isfinite(out) ? NumberStatus::kOk : NumberStatus::kNotFinite;
}

/// Where a node starts (1-based), or {0, 0} when yaml-cpp has no mark for it.
std::pair<int, int> position_of(const YAML::Node& node) {
  if (!node.IsDefined()) return {0, 0};
  const YAML::Mark m = node.Mark();
  if (m.is_null() || m.line < 0) return {0, 0};
  return {m.line + 1, m.column + 1};
}

/// Parsing context: the source name and the root mapping, for error positions.
class Reader {
 public:
  Reader(std::string source, YAML::Node root) : source_(std::move(source)), root_(std::move(root)) {}

  [[nodiscard]] Error error_at(const YAML::Node& node, std::string field, std::string message) const {
    const auto [line, column] = position_of(node);
    return Error{std::move(message), source_, line, column, std::move(field)};
  }

  /// The first of `keys` present in the root mapping (its name and node); an empty name and an
  /// undefined node when none is. (A default-constructed YAML::Node is a defined null, so the
  /// undefined node comes from the failed look-up itself.)
  [[nodiscard]] std::pair<std::string, YAML::Node> find(std::initializer_list<const char*> keys) const {
    for (const char* k : keys) {
      const YAML::Node n = root_[k];
      if (n.IsDefined()) return {k, n};
    }
    return {{}, root_[*keys.begin()]};
  }

  [[nodiscard]] Error missing(std::initializer_list<const char*> keys) const {
    std::string alternatives;
    for (const char* k : keys) {
      if (!alternatives.empty()) alternatives += " or ";
      alternatives += fmt::format("'{}'", k);
    }
    return Error{fmt::format("missing key {}", alternatives), source_, 0, 0, *keys.begin()};
  }

  /// A finite number held by a scalar node.
  [[nodiscard]] Expected<double> number(const YAML::Node& node, const std::string& field,
                                        const std::string& what) const {
    if (!node.IsScalar()) return error_at(node, field, fmt::format("{} is not a number", what));
    double v = 0.0;
    switch (parse_number(node.Scalar(), v)) {
      case NumberStatus::kOk:
        return v;
      case NumberStatus::kNotFinite:
        return error_at(node, field, fmt::format("{} is not a finite number: '{}'", what, node.Scalar()));
      case NumberStatus::kNotNumber:
        break;
    }
    return error_at(node, field, fmt::format("{} is not a number: '{}'", what, node.Scalar()));
  }

  /// An image side: a positive integer number of pixels.
  [[nodiscard]] Expected<int> image_side(std::initializer_list<const char*> keys) const {
    const auto [key, node] = find(keys);
    if (key.empty()) return missing(keys);
    Expected<double> v = number(node, key, "value");
    if (!v) return v.error();
    if (*v <= 0.0) return error_at(node, key, fmt::format("must be positive, got {}", node.Scalar()));
    if (*v != std::floor(*v) || *v > kMaxImageSide) {
      return error_at(node, key, fmt::format("must be a whole number of pixels, got {}", node.Scalar()));
    }
    return static_cast<int>(*v);
  }

  /// \brief A matrix, either an OpenCV/ROS mapping {rows, cols, [dt], data} or a flat sequence
  /// (message form; rows = size, cols = 1). Returns the values in row-major order.
  struct Matrix {
    std::vector<double> values;
    int rows = -1;  ///< -1 for a flat sequence
    int cols = -1;
  };

  [[nodiscard]] Expected<Matrix> matrix(const std::string& key, const YAML::Node& node) const {
    Matrix m;
    // Copy-construct, never assign: yaml-cpp's Node::operator= writes through to the target node.
    const YAML::Node data = node.IsMap() ? node["data"] : node;
    if (node.IsMap()) {
      if (!data.IsDefined()) return error_at(node, key, "missing 'data'");
      for (const char* dim : {"rows", "cols"}) {
        const YAML::Node d = node[dim];
        if (!d.IsDefined()) continue;
        Expected<double> v = number(d, key, dim);
        if (!v) return v.error();
        if (*v < 0.0 || *v != std::floor(*v) || *v > 1e6) {
          return error_at(d, key, fmt::format("'{}' must be a non-negative integer, got {}", dim, d.Scalar()));
        }
        (dim[0] == 'r' ? m.rows : m.cols) = static_cast<int>(*v);
      }
    }
    if (!data.IsSequence()) {
      return error_at(data, key,
                      node.IsMap() ? "'data' must be a sequence of numbers"
                                   : "expected a matrix: {rows, cols, data: [...]} or a list");
    }
    m.values.reserve(data.size());
    for (std::size_t i = 0; i < data.size(); ++i) {
      Expected<double> v = number(data[i], key, fmt::format("data[{}]", i));
      if (!v) return v.error();
      m.values.push_back(*v);
    }
    if (m.rows >= 0 || m.cols >= 0) {
      if (m.rows < 0 || m.cols < 0) {
        return error_at(
            node, key,
            fmt::format("'{}' given without '{}'", m.rows < 0 ? "cols" : "rows", m.rows < 0 ? "rows" : "cols"));
      }
      if (static_cast<std::size_t>(m.rows) * static_cast<std::size_t>(m.cols) != m.values.size()) {
        return error_at(data, key,
                        fmt::format("'data' has {} values but rows x cols = {}x{}", m.values.size(), m.rows, m.cols));
      }
    }
    return m;
  }

  /// A matrix of a fixed shape (a mapping must say rows x cols; a flat list must hold rows*cols).
  [[nodiscard]] Expected<std::vector<double>> fixed_matrix(const std::string& key, const YAML::Node& node, int rows,
                                                           int cols) const {
    Expected<Matrix> m = matrix(key, node);
    if (!m) return m.error();
    if (m->rows >= 0 && (m->rows != rows || m->cols != cols)) {
      return error_at(node, key, fmt::format("expected a {}x{} matrix, got {}x{}", rows, cols, m->rows, m->cols));
    }
    if (m->values.size() != static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols)) {
      return error_at(
          node, key,
          fmt::format("expected a {}x{} matrix ({} values), got {} values", rows, cols, rows * cols, m->values.size()));
    }
    return std::move(m->values);
  }

 private:
  std::string source_;
  YAML::Node root_;
};

/// Rewrites OpenCV FileStorage YAML into YAML that yaml-cpp accepts, keeping every line and
/// column where it was: CRLF/CR become LF, a `%YAML:1.x` directive line is blanked and the
/// `!!opencv-matrix` tags are replaced by spaces.
std::string to_plain_yaml(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '\r') {
      if (i + 1 < text.size() && text[i + 1] == '\n') continue;
      out.push_back('\n');
    } else {
      out.push_back(c);
    }
  }
  // Blank a "%YAML:" directive (OpenCV writes "%YAML:1.0", which YAML 1.2 parsers reject).
  std::size_t line_start = 0;
  while (line_start < out.size()) {
    std::size_t line_end = out.find('\n', line_start);
    if (line_end == std::string::npos) line_end = out.size();
    if (out.compare(line_start, 6, "%YAML:") == 0) {
      for (std::size_t k = line_start; k < line_end; ++k) out[k] = ' ';
    }
    line_start = line_end + 1;
  }
  for (const std::string_view tag :
       {std::string_view("!!opencv-matrix"), std::string_view("!<tag:yaml.org,2002:opencv-matrix>")}) {
    for (std::size_t p = out.find(tag); p != std::string::npos; p = out.find(tag, p + tag.size())) {
      for (std::size_t k = p; k < p + tag.size(); ++k) out[k] = ' ';
    }
  }
  return out;
}

/// Lower-case ASCII copy.
std::string lower(std::string s) {
  for (char& c : s) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return s;
}

/// Maps the file's coefficients onto k1 k2 p1 p2 k3, checking the model and the count.
Expected<std::array<double, 5>> read_distortion(const Reader& r, const std::string& key, const YAML::Node& node,
                                                const std::string& model_key, const YAML::Node& model_node) {
  std::array<double, 5> dist{0, 0, 0, 0, 0};
  std::string model;
  if (model_node.IsDefined()) {
    if (!model_node.IsScalar()) return r.error_at(model_node, model_key, "must be a string");
    model = lower(model_node.Scalar());
  }
  const bool none = model == "none";
  if (!model.empty() && !none && model != "plumb_bob" && model != "rational_polynomial") {
    return r.error_at(model_node, model_key,
                      fmt::format("unsupported distortion model '{}' (supported: plumb_bob, "
                                  "rational_polynomial with k4 = k5 = k6 = 0, none)",
                                  model_node.Scalar()));
  }
  if (!node.IsDefined()) return dist;  // no coefficients: no distortion
  Expected<Reader::Matrix> m = r.matrix(key, node);
  if (!m) return m.error();
  if (m->rows >= 0 && m->rows != 1 && m->cols != 1 && !m->values.empty()) {
    return r.error_at(node, key, fmt::format("expected a vector (1xN or Nx1), got {}x{}", m->rows, m->cols));
  }
  const std::vector<double>& d = m->values;
  if (none) {
    for (double v : d) {
      if (v != 0.0) return r.error_at(node, key, "distortion_model is 'none' but a coefficient is not zero");
    }
    return dist;
  }
  if (d.empty() && model.empty()) return r.error_at(node, key, "no distortion coefficients (expected 4, 5 or 8)");
  if (d.size() < kMinCoefficients) {
    return r.error_at(node, key, fmt::format("expected 4, 5 or 8 coefficients, got {}", d.size()));
  }
  if (model == "plumb_bob" && d.size() > kModelledCoefficients) {
    return r.error_at(node, key, fmt::format("plumb_bob has 5 coefficients, got {}", d.size()));
  }
  // 8: rational (k4 k5 k6); 12: + thin prism (s1..s4); 14: + tilt (tx, ty). v4r models none of
  // them, so they are accepted only when zero.
  if (d.size() != 4 && d.size() != 5 && d.size() != 8 && d.size() != 12 && d.size() != 14) {
    return r.error_at(node, key, fmt::format("expected 4, 5 or 8 coefficients, got {}", d.size()));
  }
  for (std::size_t i = kModelledCoefficients; i < d.size(); ++i) {
    if (d[i] == 0.0) continue;
    const char* what = i < 8    ? "rational model not supported (k4, k5, k6 must be zero)"
                       : i < 12 ? "thin prism model not supported (s1..s4 must be zero)"
                                : "tilted sensor model not supported (tauX, tauY must be zero)";
    return r.error_at(node, key, fmt::format("{}; coefficient {} is {}", what, i, d[i]));
  }
  for (std::size_t i = 0; i < std::min(d.size(), kModelledCoefficients); ++i) dist[i] = d[i];
  return dist;
}

Expected<geometry::PinholeCamera> parse_root(const Reader& r, const CameraFileOptions& opt) {
  geometry::PinholeCamera cam;
  const bool no_size = r.find({"image_width", "width"}).first.empty() && r.find({"image_height", "height"}).first.empty();
  if (!(opt.size_optional && no_size)) {
    Expected<int> w = r.image_side({"image_width", "width"});
    if (!w) return w.error();
    Expected<int> h = r.image_side({"image_height", "height"});
    if (!h) return h.error();
    cam.width = *w;
    cam.height = *h;
  }

  const auto [k_key, k_node] = r.find({"camera_matrix", "K", "k"});
  if (k_key.empty()) return r.missing({"camera_matrix", "K", "k"});
  Expected<std::vector<double>> K = r.fixed_matrix(k_key, k_node, 3, 3);
  if (!K) return K.error();
  const std::vector<double>& k = *K;
  if (k[0] <= 0.0) return r.error_at(k_node, k_key, fmt::format("fx must be positive, got {}", k[0]));
  if (k[4] <= 0.0) return r.error_at(k_node, k_key, fmt::format("fy must be positive, got {}", k[4]));
  const double tol = kStructureTolerance * std::max({1.0, k[0], k[4]});
  if (std::abs(k[6]) > kStructureTolerance || std::abs(k[7]) > kStructureTolerance ||
      std::abs(k[8] - 1.0) > kStructureTolerance) {
    return r.error_at(k_node, k_key, fmt::format("last row must be 0 0 1, got {} {} {}", k[6], k[7], k[8]));
  }
  if (std::abs(k[1]) > tol) {
    return r.error_at(k_node, k_key, fmt::format("skew must be zero, got {}", k[1]));
  }
  if (std::abs(k[3]) > tol) {
    return r.error_at(k_node, k_key, fmt::format("entry (1,0) must be zero, got {}", k[3]));
  }
  cam.fx = k[0];
  cam.cx = k[2];
  cam.fy = k[4];
  cam.cy = k[5];

  const auto [d_key, d_node] = r.find({"distortion_coefficients", "D", "d"});
  const auto [m_key, m_node] = r.find({"distortion_model"});
  Expected<std::array<double, 5>> dist = read_distortion(r, d_key.empty() ? "distortion_coefficients" : d_key, d_node,
                                                         m_key.empty() ? "distortion_model" : m_key, m_node);
  if (!dist) return dist.error();
  cam.dist = *dist;

  // Rectification and projection matrices are not used (v4r works on raw images with K and D),
  // but when present they must be well formed.
  const auto [r_key, r_node] = r.find({"rectification_matrix", "R", "r"});
  if (!r_key.empty()) {
    Expected<std::vector<double>> R = r.fixed_matrix(r_key, r_node, 3, 3);
    if (!R) return R.error();
  }
  const auto [p_key, p_node] = r.find({"projection_matrix", "P", "p"});
  if (!p_key.empty()) {
    Expected<std::vector<double>> P = r.fixed_matrix(p_key, p_node, 3, 4);
    if (!P) return P.error();
  }
  return cam;
}

/// Reads a whole file; errors name the path.
Expected<std::string> read_text(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return Error{fmt::format("file not found: {}", path), path, 0, 0, {}};
  }
  if (std::filesystem::is_directory(path, ec)) {
    return Error{fmt::format("is a directory, not a calibration file: {}", path), path, 0, 0, {}};
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{fmt::format("cannot open {}", path), path, 0, 0, {}};
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return Error{fmt::format("cannot read {}", path), path, 0, 0, {}};
  return ss.str();
}

/// A double in a form both yaml-cpp and OpenCV read back exactly and as a real ("600.", "1e-05").
std::string real(double v) {
  std::string s = fmt::format("{:.17g}", v);
  if (s.find_first_of(".eEn") == std::string::npos) s += '.';
  return s;
}

}  // namespace

Expected<geometry::PinholeCamera> parse_camera(const std::string& text, const std::string& source,
                                               const CameraFileOptions& opt) {
  std::size_t first = 0;
  if (text.compare(0, 3, "\xEF\xBB\xBF") == 0) first = 3;  // UTF-8 byte order mark
  while (first < text.size() && std::isspace(static_cast<unsigned char>(text[first]))) ++first;
  if (first < text.size() && text[first] == '<') return parse_camera_xml(text, source, opt);
  try {
    const YAML::Node root = YAML::Load(to_plain_yaml(text));
    if (!root.IsMap()) {
      const auto [line, column] = position_of(root);
      return Error{"expected a mapping of calibration keys (image_width, camera_matrix, ...)",
                   source,
                   line > 0 ? line : 1,
                   column > 0 ? column : 1,
                   {}};
    }
    const Reader reader(source, root);
    return parse_root(reader, opt);
  } catch (const YAML::Exception& e) {
    Error err{e.msg, source, 0, 0, {}};
    if (!e.mark.is_null()) {
      err.line = e.mark.line + 1;
      err.column = e.mark.column + 1;
    }
    return err;
  } catch (const std::exception& e) {
    return Error{e.what(), source, 0, 0, {}};
  }
}

Expected<geometry::PinholeCamera> load_camera(const std::string& path, const CameraFileOptions& opt) {
  Expected<std::string> text = read_text(path);
  if (!text) return text.error();
  return parse_camera(*text, path, opt);
}

Expected<void> save_camera_opencv(const std::string& path, const geometry::PinholeCamera& cam) {
  if (cam.width <= 0 || cam.height <= 0) {
    return Error{fmt::format("image size must be positive, got {}x{}", cam.width, cam.height), path, 0, 0, {}};
  }
  if (!(cam.fx > 0.0) || !(cam.fy > 0.0) || !std::isfinite(cam.fx) || !std::isfinite(cam.fy) ||
      !std::isfinite(cam.cx) || !std::isfinite(cam.cy)) {
    return Error{"focal lengths must be positive and all intrinsics finite", path, 0, 0, {}};
  }
  for (double d : cam.dist) {
    if (!std::isfinite(d)) return Error{"distortion coefficients must be finite", path, 0, 0, {}};
  }
  std::string out;
  out += "%YAML:1.0\n---\n";
  out += fmt::format("image_width: {}\nimage_height: {}\n", cam.width, cam.height);
  out += "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n";
  out += fmt::format("   data: [ {}, {}, {}, {}, {}, {}, {}, {}, {} ]\n", real(cam.fx), real(0.0), real(cam.cx),
                     real(0.0), real(cam.fy), real(cam.cy), real(0.0), real(0.0), real(1.0));
  out += "distortion_coefficients: !!opencv-matrix\n   rows: 5\n   cols: 1\n   dt: d\n";
  out += fmt::format("   data: [ {}, {}, {}, {}, {} ]\n", real(cam.dist[0]), real(cam.dist[1]), real(cam.dist[2]),
                     real(cam.dist[3]), real(cam.dist[4]));
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) return Error{fmt::format("cannot open {} for writing", path), path, 0, 0, {}};
  f << out;
  f.close();
  if (!f) return Error{fmt::format("cannot write {}", path), path, 0, 0, {}};
  return {};
}

}  // namespace v4r::io
