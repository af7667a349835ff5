// v4r - robust model-based object tracking. MIT licence.
//
// XML calibration files. A small reader of the XML subset these files use (elements, text,
// attributes skipped, comments, the <?xml?> declaration), keeping the line and column of every
// element for the error messages.

#include "camera_xml.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <string_view>
#include <vector>

namespace v4r::io {
namespace {

constexpr int kMaxDepth = 32;
constexpr double kMaxImageSide = 1'000'000.0;

struct Element {
  std::string name, text;
  int line = 0, column = 0;
  std::vector<Element> children;

  [[nodiscard]] const Element* child(std::string_view n) const {
    for (const Element& c : children)
      if (c.name == n) return &c;
    return nullptr;
  }
};

class XmlReader {
 public:
  XmlReader(const std::string& text, const std::string& source) : s_(text), source_(source) {}

  Expected<Element> document() {
    skip_misc();
    if (i_ >= s_.size() || s_[i_] != '<') return fail("expected an XML element");
    Element root;
    if (auto r = element(root, 0); !r) return r.error();
    skip_misc();
    if (i_ < s_.size()) return fail("text after the root element");
    return root;
  }

 private:
  Error fail(const std::string& what) const { return Error{what, source_, line_, col_, {}}; }

  void advance(std::size_t n = 1) {
    for (std::size_t k = 0; k < n && i_ < s_.size(); ++k, ++i_) {
      if (s_[i_] == '\n') {
        ++line_;
        col_ = 1;
      } else {
        ++col_;
      }
    }
  }
  bool starts(std::string_view p) const { return s_.compare(i_, p.size(), p) == 0; }
  bool skip_until(std::string_view end) {
    while (i_ < s_.size() && !starts(end)) advance();
    if (i_ >= s_.size()) return false;
    advance(end.size());
    return true;
  }
  /// Whitespace, comments, declarations and processing instructions.
  void skip_misc() {
    while (i_ < s_.size()) {
      if (std::isspace(static_cast<unsigned char>(s_[i_]))) {
        advance();
      } else if (starts("<!--")) {
        skip_until("-->");
      } else if (starts("<?")) {
        skip_until("?>");
      } else if (starts("<!")) {
        skip_until(">");
      } else if (starts("\xEF\xBB\xBF")) {
        i_ += 3;
      } else {
        break;
      }
    }
  }

  Expected<void> element(Element& e, int depth) {
    if (depth > kMaxDepth) return fail("elements nested too deeply");
    e.line = line_;
    e.column = col_;
    advance();  // '<'
    while (i_ < s_.size() && !std::isspace(static_cast<unsigned char>(s_[i_])) && s_[i_] != '>' && s_[i_] != '/')
      e.name.push_back(s_[i_]), advance();
    if (e.name.empty()) return fail("expected an element name after '<'");
    // Attributes are skipped (type_id="opencv-matrix" says nothing the children do not).
    char quote = 0;
    while (i_ < s_.size() && (quote != 0 || (s_[i_] != '>' && !starts("/>")))) {
      if (quote == 0 && (s_[i_] == '"' || s_[i_] == '\'')) {
        quote = s_[i_];
      } else if (s_[i_] == quote) {
        quote = 0;
      }
      advance();
    }
    if (i_ >= s_.size()) return fail(fmt::format("<{}> is not closed", e.name));
    if (starts("/>")) {
      advance(2);
      return {};
    }
    advance();  // '>'
    while (true) {
      if (i_ >= s_.size()) return fail(fmt::format("end of file inside <{}> (line {})", e.name, e.line));
      if (starts("<!--")) {
        skip_until("-->");
      } else if (starts("<![CDATA[")) {
        advance(9);
        while (i_ < s_.size() && !starts("]]>")) e.text.push_back(s_[i_]), advance();
        advance(3);
      } else if (starts("</")) {
        advance(2);
        std::string name;
        while (i_ < s_.size() && s_[i_] != '>') name.push_back(s_[i_]), advance();
        while (!name.empty() && std::isspace(static_cast<unsigned char>(name.back()))) name.pop_back();
        if (name != e.name) return fail(fmt::format("</{}> closes <{}> (line {})", name, e.name, e.line));
        advance();
        return {};
      } else if (s_[i_] == '<') {
        Element c;
        if (auto r = element(c, depth + 1); !r) return r;
        e.children.push_back(std::move(c));
      } else {
        e.text.push_back(s_[i_]);
        advance();
      }
    }
  }

  const std::string& s_;
  std::string source_;
  std::size_t i_ = 0;
  int line_ = 1, col_ = 1;
};

class Builder {
 public:
  explicit Builder(std::string source) : source_(std::move(source)) {}

  [[nodiscard]] Error at(const Element& e, const std::string& what) const {
    return Error{what, source_, e.line, e.column, e.name};
  }
  [[nodiscard]] Error missing(const Element& parent, const std::string& name) const {
    return Error{fmt::format("missing element <{}> in <{}>", name, parent.name), source_, parent.line, parent.column,
                 name};
  }

  /// The numbers of an element's text (blank or comma separated).
  [[nodiscard]] Expected<std::vector<double>> numbers(const Element& e) const {
    std::vector<double> v;
    std::string token;
    const auto flush = [&]() -> Expected<void> {
      if (token.empty()) return {};
      char* end = nullptr;
      const double x = std::strtod(token.c_str(), &end);
      if (end == token.c_str() || *end != '\0')
        return at(e, fmt::format("value {} is not a number: '{}'", v.size(), token));
      if (!std::isfinite(x)) return at(e, fmt::format("value {} is not a finite number: '{}'", v.size(), token));
      v.push_back(x);
      token.clear();
      return {};
    };
    for (char c : e.text) {
      if (std::isspace(static_cast<unsigned char>(c)) || c == ',') {
        if (auto r = flush(); !r) return r.error();
      } else {
        token.push_back(c);
      }
    }
    if (auto r = flush(); !r) return r.error();
    return v;
  }
  [[nodiscard]] Expected<double> number(const Element& parent, const char* name) const {
    const Element* e = parent.child(name);
    if (e == nullptr) return missing(parent, name);
    auto v = numbers(*e);
    if (!v) return v.error();
    if (v->size() != 1) return at(*e, fmt::format("expected one number, got {}", v->size()));
    return v->front();
  }
  [[nodiscard]] Expected<int> side(const Element& parent, const char* name) const {
    auto v = number(parent, name);
    if (!v) return v.error();
    const Element& e = *parent.child(name);
    if (*v <= 0.0) return at(e, fmt::format("must be positive, got {}", *v));
    if (*v != std::floor(*v) || *v > kMaxImageSide) return at(e, fmt::format("must be a whole number of pixels, got {}", *v));
    return static_cast<int>(*v);
  }
  /// The image size, or 0 x 0 when both are missing and that is allowed.
  [[nodiscard]] Expected<void> size(const Element& parent, const CameraFileOptions& opt,
                                    geometry::PinholeCamera& cam) const {
    if (opt.size_optional && parent.child("image_width") == nullptr && parent.child("image_height") == nullptr)
      return {};
    auto w = side(parent, "image_width");
    if (!w) return w.error();
    auto h = side(parent, "image_height");
    if (!h) return h.error();
    cam.width = *w;
    cam.height = *h;
    return {};
  }
  /// An OpenCV matrix element: <rows>, <cols>, <dt>, <data>.
  [[nodiscard]] Expected<std::vector<double>> matrix(const Element& e) const {
    const Element* data = e.child("data");
    if (data == nullptr) return missing(e, "data");
    auto v = numbers(*data);
    if (!v) return v.error();
    const Element* rows = e.child("rows");
    const Element* cols = e.child("cols");
    if (rows != nullptr && cols != nullptr) {
      auto r = number(e, "rows");
      if (!r) return r.error();
      auto c = number(e, "cols");
      if (!c) return c.error();
      if (*r * *c != static_cast<double>(v->size()))
        return at(*data, fmt::format("<data> has {} values but rows x cols = {}x{}", v->size(), *r, *c));
    }
    return v;
  }

  [[nodiscard]] Expected<void> intrinsics(const Element& e, double fx, double fy, geometry::PinholeCamera& cam) const {
    if (!(fx > 0.0)) return at(e, fmt::format("fx must be positive, got {}", fx));
    if (!(fy > 0.0)) return at(e, fmt::format("fy must be positive, got {}", fy));
    cam.fx = fx;
    cam.fy = fy;
    return {};
  }

 private:
  std::string source_;
};

Expected<geometry::PinholeCamera> opencv_xml(const Element& root, const Builder& b, const CameraFileOptions& opt) {
  geometry::PinholeCamera cam;
  if (auto r = b.size(root, opt, cam); !r) return r.error();
  const Element* k = root.child("camera_matrix");
  if (k == nullptr) return b.missing(root, "camera_matrix");
  auto K = b.matrix(*k);
  if (!K) return K.error();
  if (K->size() != 9) return b.at(*k, fmt::format("expected a 3x3 matrix (9 values), got {} values", K->size()));
  const std::vector<double>& m = *K;
  if (std::abs(m[6]) > 1e-9 || std::abs(m[7]) > 1e-9 || std::abs(m[8] - 1.0) > 1e-9)
    return b.at(*k, fmt::format("last row must be 0 0 1, got {} {} {}", m[6], m[7], m[8]));
  if (std::abs(m[1]) > 1e-9 * std::max({1.0, m[0], m[4]})) return b.at(*k, fmt::format("skew must be zero, got {}", m[1]));
  if (auto r = b.intrinsics(*k, m[0], m[4], cam); !r) return r.error();
  cam.cx = m[2];
  cam.cy = m[5];
  if (const Element* d = root.child("distortion_coefficients"); d != nullptr) {
    auto D = b.matrix(*d);
    if (!D) return D.error();
    const std::vector<double>& v = *D;
    if (!v.empty() && v.size() != 4 && v.size() != 5 && v.size() != 8 && v.size() != 12 && v.size() != 14)
      return b.at(*d, fmt::format("expected 4, 5 or 8 coefficients, got {}", v.size()));
    for (std::size_t i = 5; i < v.size(); ++i)
      if (v[i] != 0.0)
        return b.at(*d, fmt::format("only k1 k2 p1 p2 k3 are modelled: coefficient {} must be zero, is {}", i, v[i]));
    for (std::size_t i = 0; i < std::min<std::size_t>(5, v.size()); ++i) cam.dist[i] = v[i];
  }
  return cam;
}

Expected<geometry::PinholeCamera> visp_xml(const Element& root, const Builder& b, const CameraFileOptions& opt) {
  const Element* camera = root.child("camera");
  if (camera == nullptr) return b.missing(root, "camera");
  geometry::PinholeCamera cam;
  if (auto r = b.size(*camera, opt, cam); !r) return r.error();
  const Element* with = nullptr;
  const Element* without = nullptr;
  for (const Element& m : camera->children) {
    if (m.name != "model") continue;
    const Element* type = m.child("type");
    if (type == nullptr) return b.missing(m, "type");
    std::string t = type->text;
    t.erase(std::remove_if(t.begin(), t.end(), [](unsigned char c) { return std::isspace(c) != 0; }), t.end());
    if (t == "perspectiveProjWithDistortion") {
      if (with == nullptr) with = &m;
    } else if (t == "perspectiveProjWithoutDistortion") {
      if (without == nullptr) without = &m;
    } else {
      return b.at(*type, fmt::format("unsupported camera model '{}' (perspectiveProjWithDistortion, "
                                     "perspectiveProjWithoutDistortion)",
                                     t));
    }
  }
  const Element* m = with != nullptr ? with : without;
  if (m == nullptr) return b.missing(*camera, "model");
  auto px = b.number(*m, "px");
  if (!px) return px.error();
  auto py = b.number(*m, "py");
  if (!py) return py.error();
  auto u0 = b.number(*m, "u0");
  if (!u0) return u0.error();
  auto v0 = b.number(*m, "v0");
  if (!v0) return v0.error();
  if (auto r = b.intrinsics(*m, *px, *py, cam); !r) return r.error();
  cam.cx = *u0;
  cam.cy = *v0;
  if (m == with) {
    // ViSP's kud maps undistorted to distorted normalised coordinates, x_d = x (1 + kud r^2):
    // OpenCV's k1 with the other coefficients zero.
    auto kud = b.number(*m, "kud");
    if (!kud) return kud.error();
    cam.dist[0] = *kud;
  }
  return cam;
}

}  // namespace

Expected<geometry::PinholeCamera> parse_camera_xml(const std::string& text, const std::string& source,
                                                   const CameraFileOptions& opt) {
  XmlReader reader(text, source);
  Expected<Element> root = reader.document();
  if (!root) return root.error();
  const Builder b(source);
  if (root->name == "opencv_storage") return opencv_xml(*root, b, opt);
  if (root->name == "root" && root->child("camera") != nullptr) return visp_xml(*root, b, opt);
  return b.at(*root, fmt::format("unknown XML calibration <{}>: expected <opencv_storage> (OpenCV FileStorage) or "
                                 "<root><camera> (ViSP camera parameters)",
                                 root->name));
}

}  // namespace v4r::io
