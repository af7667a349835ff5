// v4r - robust model-based object tracking. MIT licence.
#include "v4r/io/scene_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <utility>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "v4r/io/camera_io.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/model_colour.hpp"

// GCC 12 reports a dangling pointer inside yaml-cpp 0.7's inlined Node accessors (node/impl.h), a
// known false positive of that header; it is silenced for this file only.
#pragma GCC diagnostic ignored "-Wdangling-pointer"

namespace v4r::io {

namespace fs = std::filesystem;

namespace {

constexpr double kTwoPi = 6.283185307179586;

/// Reads one scene file: the source name for errors and the folder relative paths start from.
class SceneReader {
 public:
  SceneReader(std::string source, std::string base_dir) : source_(std::move(source)), base_(std::move(base_dir)) {}

  [[nodiscard]] int line_of(const YAML::Node& node) const {
    if (!node.IsDefined()) return 0;
    const YAML::Mark m = node.Mark();
    return m.is_null() || m.line < 0 ? 0 : m.line + 1;
  }

  [[nodiscard]] Error error_at(const YAML::Node& node, std::string field, std::string message) const {
    return Error{std::move(message), source_, line_of(node), 0, std::move(field)};
  }

  [[nodiscard]] SceneFileMark mark(const YAML::Node& node, std::string field) const {
    return SceneFileMark{source_, line_of(node), std::move(field)};
  }

  /// A path of the file, relative ones taken from the scene file's folder.
  [[nodiscard]] std::string resolve(const std::string& p) const {
    if (p.empty() || fs::path(p).is_absolute() || base_.empty()) return p;
    return (fs::path(base_) / p).lexically_normal().string();
  }

  /// An input that is no path: a live camera or a registered scheme ("gst:...", "ros2:/topic").
  [[nodiscard]] static bool is_not_a_path(const std::string& in) {
    if (is_live_input(in)) return true;
    const auto colon = in.find(':');
    const auto slash = in.find('/');
    return colon != std::string::npos && colon > 1 && (slash == std::string::npos || colon < slash);
  }

  /// The string value of a required scalar field.
  Expected<std::string> scalar(const YAML::Node& entry, const char* key, const std::string& field) const {
    const YAML::Node v = entry[key];
    if (!v.IsDefined() || v.IsNull()) return error_at(entry, field, "missing (required)");
    if (!v.IsScalar()) return error_at(v, field, "expected a single value");
    if (v.Scalar().empty()) return error_at(v, field, "empty");
    return v.Scalar();
  }

  /// A camera's or object's name: it names files (D/<object>.csv, DIR/<camera>/), so letters,
  /// digits, '_', '-' and '.', not starting with '.'.
  Expected<std::string> name(const YAML::Node& entry, const std::string& field) const {
    auto n = scalar(entry, "name", field);
    if (!n) return n;
    const bool ok = std::all_of(n->begin(), n->end(), [](char ch) {
      return std::isalnum(static_cast<unsigned char>(ch)) != 0 || ch == '_' || ch == '-' || ch == '.';
    });
    if (!ok || n->front() == '.')
      return error_at(entry["name"], field,
                      fmt::format("'{}': a name may hold letters, digits, '_', '-' and '.' (not first): it names files",
                                  *n));
    return n;
  }

  /// Six pose numbers [tx, ty, tz, rx, ry, rz]: metres and a rotation vector in radians.
  Expected<PoseNumbers> pose(const YAML::Node& v, const std::string& field) const {
    if (!v.IsSequence() || v.size() != 6)
      return error_at(v, field, "expected six numbers [tx, ty, tz, rx, ry, rz] (m, rad)");
    PoseNumbers n{};
    for (std::size_t i = 0; i < 6; ++i) {
      const YAML::Node x = v[i];
      double d = 0.0;
      if (!x.IsScalar() || !YAML::convert<double>::decode(x, d))
        return error_at(x, field, fmt::format("element {} is not a number: '{}'", i + 1, x.IsScalar() ? x.Scalar() : "?"));
      if (!std::isfinite(d)) return error_at(x, field, fmt::format("element {} is not finite", i + 1));
      n[i] = d;
    }
    const double angle = std::sqrt(n[3] * n[3] + n[4] * n[4] + n[5] * n[5]);
    if (angle > kTwoPi + 1e-9)
      return error_at(v, field,
                      fmt::format("the rotation vector is {:.3f} rad long, more than 2 pi: give radians (Rodrigues)", angle));
    return n;
  }

  /// `tag:` as `--tag` takes it (detection::parse_tag_spec): "family:id:size_m:tx ty tz rx ry rz".
  Expected<detection::TagSpec> tag(const YAML::Node& v, const std::string& field) const {
    if (!v.IsScalar())
      return error_at(v, field, "expected one string \"family:id:size_m:tx ty tz rx ry rz\" (as --tag)");
    auto t = detection::parse_tag_spec(v.Scalar(), field);
    if (!t) return error_at(v, field, without_prefix(t.error().message, field));
    return t;
  }

  /// `colour: [R, G, B]` (or "R,G,B"), each in 0..1, as `--colour` takes it (model::parse_colour).
  Expected<Eigen::Vector3f> colour(const YAML::Node& v, const std::string& field) const {
    std::string text;
    if (v.IsScalar()) {
      text = v.Scalar();
    } else if (v.IsSequence()) {
      for (std::size_t i = 0; i < v.size(); ++i) {
        if (!v[i].IsScalar()) return error_at(v[i], field, fmt::format("element {} is not a number", i + 1));
        text += (i == 0 ? "" : ",") + v[i].Scalar();
      }
    } else {
      return error_at(v, field, "expected three numbers [R, G, B], each in 0..1");
    }
    auto c = model::parse_colour(text, field);
    if (!c) return error_at(v, field, c.error().message);
    return c;
  }

  /// A message of a parser that starts with the field it was given ("field: ..."), without it.
  static std::string without_prefix(const std::string& message, const std::string& field) {
    const std::string prefix = field + ": ";
    return message.starts_with(prefix) ? message.substr(prefix.size()) : message;
  }

  Expected<void> check_keys(const YAML::Node& map, const std::set<std::string>& allowed, const std::string& where) const {
    for (auto it = map.begin(); it != map.end(); ++it) {
      const std::string key = it->first.IsScalar() ? it->first.Scalar() : std::string("?");
      if (allowed.count(key) == 0) {
        std::string list;
        for (const std::string& a : allowed) list += (list.empty() ? "" : ", ") + a;
        return error_at(it->first, where.empty() ? key : where + "." + key,
                        fmt::format("unknown key (expected one of: {})", list));
      }
    }
    return {};
  }

  Expected<SceneCameraSpec> camera(const YAML::Node& e, std::size_t i) const {
    const std::string f = fmt::format("cameras[{}]", i);
    if (!e.IsMap()) return error_at(e, f, "expected a mapping with name, calibration, input, T_ref_cam");
    if (auto k = check_keys(e, {"name", "calibration", "input", "T_ref_cam"}, f); !k) return k.error();
    SceneCameraSpec c;
    c.at = mark(e, f);
    auto n = name(e, f + ".name");
    if (!n) return n.error();
    c.name = *n;
    auto calib = scalar(e, "calibration", f + ".calibration");
    if (!calib) return calib.error();
    c.calibration_path = resolve(*calib);
    std::error_code ec;
    if (!fs::is_regular_file(c.calibration_path, ec))
      return error_at(e["calibration"], f + ".calibration", fmt::format("no such file: {}", c.calibration_path));
    auto cam = load_camera(c.calibration_path, CameraFileOptions{.size_optional = true});
    if (!cam)
      return error_at(e["calibration"], f + ".calibration",
                      fmt::format("the calibration does not load: {}", cam.error().to_string()));
    c.calibration = *cam;
    if (const YAML::Node in = e["input"]; in.IsDefined() && !in.IsNull()) {
      auto s = scalar(e, "input", f + ".input");
      if (!s) return s.error();
      c.input_at = mark(in, f + ".input");
      if (is_not_a_path(*s)) {
        c.input = *s;
      } else {
        // A folder, a video or a printf pattern (whose folder) must exist.
        c.input = resolve(*s);
        const fs::path p = c.input.find('%') != std::string::npos ? fs::path(c.input).parent_path() : fs::path(c.input);
        if (!p.empty() && !fs::exists(p, ec))
          return error_at(in, f + ".input", fmt::format("no such file or folder: {}", p.string()));
      }
    }
    if (const YAML::Node t = e["T_ref_cam"]; t.IsDefined() && !t.IsNull()) {
      auto n = pose(t, f + ".T_ref_cam");
      if (!n) return n.error();
      c.T_ref_cam = pose_from_numbers(*n);
    }
    return c;
  }

  Expected<SceneObjectSpec> object(const YAML::Node& e, std::size_t i) const {
    const std::string f = fmt::format("objects[{}]", i);
    if (!e.IsMap()) return error_at(e, f, "expected a mapping with name, model, init_pose");
    if (auto k = check_keys(e, {"name", "model", "mesh_scale", "model_units", "init_pose", "tag", "colour"}, f); !k) return k.error();
    SceneObjectSpec o;
    o.at = mark(e, f);
    auto n = name(e, f + ".name");
    if (!n) return n.error();
    o.name = *n;
    auto model = scalar(e, "model", f + ".model");
    if (!model) return model.error();
    o.model_path = resolve(*model);
    o.model_at = mark(e["model"], f + ".model");
    std::error_code ec;
    if (!fs::is_regular_file(o.model_path, ec))
      return error_at(e["model"], f + ".model", fmt::format("no such file: {}", o.model_path));
    bool scale_given = false;
    if (const YAML::Node s = e["mesh_scale"]; s.IsDefined()) {
      double d = 0.0;
      if (!s.IsScalar() || !YAML::convert<double>::decode(s, d) || !std::isfinite(d) || d < 1e-9 || d > 1e9)
        return error_at(s, f + ".mesh_scale", "expected a number in [1e-9, 1e9] (model units -> metres)");
      o.scale = d;
      scale_given = true;
    }
    if (const YAML::Node u = e["model_units"]; u.IsDefined()) {
      const std::string units = u.IsScalar() ? u.Scalar() : std::string();
      double d = 0.0;
      if (units == "mm") {
        d = 1e-3;
      } else if (units == "cm") {
        d = 1e-2;
      } else if (units == "m") {
        d = 1.0;
      } else {
        return error_at(u, f + ".model_units", fmt::format("expected mm, cm or m, got '{}'", units));
      }
      if (scale_given && d != o.scale)
        return error_at(u, f + ".model_units",
                        fmt::format("model_units {} means mesh_scale {}, but mesh_scale {} is given", units, d, o.scale));
      o.scale = d;
    }
    if (const YAML::Node p = e["init_pose"]; p.IsDefined() && !p.IsNull()) {
      auto n = pose(p, f + ".init_pose");
      if (!n) return n.error();
      o.init_numbers = *n;
      o.init_pose = pose_from_numbers(*n);
    }
    if (const YAML::Node t = e["tag"]; t.IsDefined() && !t.IsNull()) {
      auto v = tag(t, f + ".tag");
      if (!v) return v.error();
      o.tag = std::move(*v);
      o.tag_at = mark(t, f + ".tag");
    }
    if (const YAML::Node c = e["colour"]; c.IsDefined() && !c.IsNull()) {
      auto v = colour(c, f + ".colour");
      if (!v) return v.error();
      o.colour = *v;
    }
    return o;
  }

  Expected<SceneFile> read(const YAML::Node& root) const {
    if (!root.IsDefined() || root.IsNull()) return Error{"the scene file is empty: it needs `cameras:`", source_, 1, 0, "cameras"};
    if (!root.IsMap()) return error_at(root, "", "a scene file is a mapping with `cameras:` and `objects:`");
    if (auto k = check_keys(root, {"reference_frame", "cameras", "objects"}, ""); !k) return k.error();
    SceneFile s;
    s.path = source_;
    if (const YAML::Node r = root["reference_frame"]; r.IsDefined()) {
      auto v = scalar(root, "reference_frame", "reference_frame");
      if (!v) return v.error();
      s.reference_frame = *v;
    }
    const YAML::Node cams = root["cameras"];
    if (!cams.IsDefined() || cams.IsNull()) return error_at(root, "cameras", "no cameras: a scene needs at least one");
    if (!cams.IsSequence()) return error_at(cams, "cameras", "expected a list of cameras (- name: ...)");
    if (cams.size() == 0) return error_at(cams, "cameras", "no cameras: a scene needs at least one");
    std::set<std::string> names;
    for (std::size_t i = 0; i < cams.size(); ++i) {
      auto c = camera(cams[i], i);
      if (!c) return c.error();
      if (!names.insert(c->name).second)
        return error_at(cams[i]["name"], fmt::format("cameras[{}].name", i), fmt::format("duplicate camera name '{}'", c->name));
      s.cameras.push_back(std::move(*c));
    }
    s.objects_at = SceneFileMark{source_, 1, "objects"};
    if (const YAML::Node objs = root["objects"]; objs.IsDefined()) s.objects_at.line = std::max(1, line_of(objs));
    if (const YAML::Node objs = root["objects"]; objs.IsDefined() && !objs.IsNull()) {
      if (!objs.IsSequence()) return error_at(objs, "objects", "expected a list of objects (- name: ...)");
      names.clear();
      for (std::size_t i = 0; i < objs.size(); ++i) {
        auto o = object(objs[i], i);
        if (!o) return o.error();
        if (!names.insert(o->name).second)
          return error_at(objs[i]["name"], fmt::format("objects[{}].name", i), fmt::format("duplicate object name '{}'", o->name));
        s.objects.push_back(std::move(*o));
      }
    }
    return s;
  }

 private:
  std::string source_, base_;
};

}  // namespace

Expected<SceneFile> parse_scene_file(const std::string& text, const std::string& source, const std::string& base_dir) {
  const SceneReader reader(source, base_dir);
  try {
    const YAML::Node root = YAML::Load(text);
    return reader.read(root);
  } catch (const YAML::Exception& ex) {
    return Error{ex.msg, source, ex.mark.line + 1, ex.mark.column + 1, {}};
  } catch (const std::exception& ex) {
    return Error{ex.what(), source, 0, 0, {}};
  }
}

Expected<SceneFile> load_scene_file(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return make_error(path, 0, 0, "no such scene file");
  std::ifstream f(path, std::ios::binary);
  if (!f) return make_error(path, 0, 0, "cannot open the scene file");
  std::stringstream ss;
  ss << f.rdbuf();
  return parse_scene_file(ss.str(), path, fs::path(path).parent_path().string());
}

}  // namespace v4r::io
