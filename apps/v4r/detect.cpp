// v4r - robust model-based object tracking. MIT licence.
// `v4r prepare` (build the detector's templates ahead of time) and `v4r detect` (find an object
// in one image without an initial pose and print the verified poses).
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app.hpp"
#include "progress.hpp"
#include "v4r/detection/detector.hpp"
#include "v4r/detection/template_cache.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/io/config_io.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/model_colour.hpp"
#include "v4r/pipeline/params.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::app {

namespace {

/// \brief Arguments shared by `v4r prepare` and `v4r detect`.
struct DetectArgs {
  std::string model, camera, input, views, cache_dir, config_file, colour;
  std::vector<std::string> sets;
  ModelUnitsArgs units;
  bool all = false, progress = false;
};

/// Parses `--views` ("elevation=15:75,azimuth=0:360,inplane=-30:30,distance=0.4:1.0"; degrees and
/// metres; any subset) into the view range.
Expected<void> parse_views(const std::string& spec, detection::ViewRange& v) {
  std::stringstream ss(spec);
  for (std::string item; std::getline(ss, item, ',');) {
    if (item.empty()) continue;
    const auto eq = item.find('='), colon = item.find(':');
    if (eq == std::string::npos || colon == std::string::npos || colon < eq)
      return make_error("--views", 0, 0, fmt::format("'{}': expected name=min:max (elevation, azimuth, inplane, distance)", item));
    const std::string name = item.substr(0, eq);
    double lo = 0, hi = 0;
    try {
      std::size_t n1 = 0, n2 = 0;
      lo = std::stod(item.substr(eq + 1, colon - eq - 1), &n1);
      hi = std::stod(item.substr(colon + 1), &n2);
      if (n1 != colon - eq - 1 || n2 != item.size() - colon - 1) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
      return make_error("--views", 0, 0, fmt::format("'{}': min and max must be numbers", item));
    }
    if (name == "elevation") {
      v.elevation_min_deg = lo;
      v.elevation_max_deg = hi;
    } else if (name == "azimuth") {
      v.azimuth_min_deg = lo;
      v.azimuth_max_deg = hi;
    } else if (name == "inplane") {
      v.inplane_min_deg = lo;
      v.inplane_max_deg = hi;
    } else if (name == "distance") {
      v.distance_min_m = lo;
      v.distance_max_m = hi;
    } else {
      return make_error("--views", 0, 0, fmt::format("unknown view range '{}' (elevation, azimuth, inplane, distance)", name));
    }
  }
  return {};
}

/// Parameters from --config, --set and --views (in that order), validated.
Expected<void> detector_params(const DetectArgs& a, detection::DetectorParams& p) {
  pipeline::CycleParams cycle;  // a config file may hold the tracker's parameters too
  ParamRegistry reg = pipeline::make_registry(cycle);
  detection::add_params(reg, p);
  if (!a.config_file.empty())
    if (auto r = io::apply_config_file(a.config_file, reg); !r) return r;
  for (const std::string& kv : a.sets) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos) return make_error(fmt::format("--set expects key=value, got '{}'", kv));
    if (auto r = reg.set(kv.substr(0, eq), kv.substr(eq + 1)); !r) {
      Error e = r.error();
      e.file = "--set";
      return Unexpected{std::move(e)};
    }
  }
  if (auto r = parse_views(a.views, p.views); !r) return r;
  return detection::validate(p);
}

/// \brief "templates 1234/52000 (2 %)" on stderr, rewritten in place at most 4 times a second.
class BuildBar {
 public:
  explicit BuildBar(bool on) : on_(on) {}
  ~BuildBar() { finish(); }
  void finish() {
    if (shown_) fmt::print(stderr, "\n");
    shown_ = false;
  }
  void operator()(std::size_t done, std::size_t total) {
    if (!on_) return;
    const auto now = std::chrono::steady_clock::now();
    if (done < total && now - last_ < std::chrono::milliseconds(250)) return;
    last_ = now;
    shown_ = true;
    fmt::print(stderr, "\r  templates {}/{} ({:.0f} %)   ", done, total, 100.0 * done / std::max<std::size_t>(1, total));
    std::fflush(stderr);
  }

 private:
  bool on_;
  bool shown_ = false;
  std::chrono::steady_clock::time_point last_{};
};

struct Loaded {
  std::shared_ptr<const model::Model> model;
  geometry::PinholeCamera cam;
  detection::DetectorParams params;
  std::shared_ptr<const detection::TemplateSet> templates;
};

Expected<Loaded> load_all(const DetectArgs& a, const char* cmd) {
  Loaded l;
  if (auto r = detector_params(a, l.params); !r) return r.error();
  auto scale = model_scale(a.units);
  if (!scale) return scale.error();
  auto m = load_model(a.model, *scale);
  if (!m) return m.error();
  l.model = *m;
  if (!a.colour.empty()) {
    auto c = model::parse_colour(a.colour, "--colour");
    if (!c) return c.error();
    l.model = with_colour(l.model, *c);
  }
  if (a.camera.empty()) {
    l.cam = synth::default_camera();
  } else {
    auto c = io::load_camera(a.camera);
    if (!c) return c.error();
    l.cam = *c;
  }
  detection::CacheReport rep;
  const auto t0 = std::chrono::steady_clock::now();
  BuildBar bar(a.progress || stderr_is_terminal());
  auto ts = detection::load_or_build(*l.model, l.cam, l.params, a.cache_dir, &rep,
                                     [&bar](std::size_t d, std::size_t t) { bar(d, t); });
  bar.finish();
  if (!ts) return ts.error();
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  l.templates = *ts;
  if (rep.built) {
    fmt::print(stderr, "v4r {}: built {} view templates ({} coarse) in {:.1f} s ({})\n", cmd, l.templates->views.size(),
               l.templates->coarse.templates.size(), s, rep.reason);
    if (rep.written) fmt::print(stderr, "v4r {}: cached in {}\n", cmd, rep.path);
    else fmt::print(stderr, "v4r {}: warning: not cached: {}\n", cmd, rep.write_error);
  } else {
    fmt::print(stderr, "v4r {}: templates from the cache {}\n", cmd, rep.path);
  }
  return l;
}

int run_prepare(const DetectArgs& a) {
  auto l = load_all(a, "prepare");
  if (!l) {
    fmt::print(stderr, "v4r prepare: error: {}\n", l.error().to_string());
    return 1;
  }
  const auto& v = l->params.views;
  fmt::print("templates of {} ready: {} views, elevation {}..{} deg, azimuth {}..{} deg, in-plane {}..{} deg, distance {}..{} m\n",
             a.model, l->templates->views.size(), v.elevation_min_deg, v.elevation_max_deg, v.azimuth_min_deg,
             v.azimuth_max_deg, v.inplane_min_deg, v.inplane_max_deg, v.distance_min_m, v.distance_max_m);
  return 0;
}

int run_detect(const DetectArgs& a) {
  const cv::Mat img = cv::imread(a.input, cv::IMREAD_UNCHANGED);
  if (img.empty()) {
    fmt::print(stderr, "v4r detect: error: {}: cannot read the image\n", a.input);
    return 1;
  }
  auto l = load_all(a, "detect");
  if (!l) {
    fmt::print(stderr, "v4r detect: error: {}\n", l.error().to_string());
    return 1;
  }
  geometry::PinholeCamera cam = l->cam;
  if (cam.width == 0 || cam.height == 0) {
    cam.width = img.cols;
    cam.height = img.rows;
  }
  if (img.cols != cam.width || img.rows != cam.height) {
    fmt::print(stderr, "v4r detect: error: {}: the image is {}x{}, the camera {}x{}\n", a.input, img.cols, img.rows, cam.width,
               cam.height);
    return 1;
  }
  cv::Mat bgr, grey;
  if (img.type() == CV_8UC3) bgr = img;
  else if (img.type() == CV_8UC4) cv::cvtColor(img, bgr, cv::COLOR_BGRA2BGR);
  else if (img.type() == CV_8UC1) grey = img;
  else {
    fmt::print(stderr, "v4r detect: error: {}: only 8-bit grey or colour images are supported\n", a.input);
    return 1;
  }
  detection::Detector det(l->model, l->templates, cam, l->params);
  std::array<detection::Hypothesis, 64> hyp;
  const detection::DetectionResult r = bgr.empty() ? det.detect(io::as_view(grey), hyp) : det.detect(io::as_colour_view(bgr), hyp);
  fmt::print("# T_cam_obj as tx ty tz rx ry rz (m, rad); score: share of model edge samples matched (accept >= {})\n",
             l->params.verify.accept_score);
  int printed = 0;
  for (int i = 0; i < r.hypotheses; ++i) {
    const auto& h = hyp[static_cast<std::size_t>(i)];
    if (!h.verified && !a.all) continue;
    const Eigen::Vector3d t = h.T_cam_obj.translation(), w = h.T_cam_obj.rvec();
    fmt::print("pose {:.5f} {:.5f} {:.5f} {:.5f} {:.5f} {:.5f} score={:.3f} samples={} {}\n", t.x(), t.y(), t.z(), w.x(), w.y(),
               w.z(), h.verification.score, h.verification.samples, h.verified ? "verified" : "rejected");
    ++printed;
  }
  if (r.colour_regions >= 0)
    fmt::print("# colour stage: {} region(s) of the model's colour searched ({:.1f} ms)\n", r.colour_regions, r.colour_ms);
  fmt::print("# {} verified of {} hypotheses; {:.1f} ms (gradients {:.1f}, search {:.1f}, refine and verify {:.1f})\n",
             r.verified, r.hypotheses, r.total_ms, r.gradient_ms, r.search_ms, r.refine_ms);
  if (r.verified == 0) {
    fmt::print(stderr, "v4r detect: no verified pose of {} in {}\n", a.model, a.input);
    return 3;
  }
  return 0;
}

void add_shared(CLI::App* c, DetectArgs& a) {
  c->add_option("--model", a.model, "box, ship, flange, section, sponge, a .cao file or a mesh (.obj, .ply, .stl)")->required();
  c->add_option("--views", a.views,
                "View range: elevation=MIN:MAX,azimuth=MIN:MAX,inplane=MIN:MAX (degrees),distance=MIN:MAX (m); "
                "any subset, the rest from detect.views.*");
  c->add_option("--cache-dir", a.cache_dir, "Template cache folder (default: $XDG_CACHE_HOME/v4r or ~/.cache/v4r)");
  c->add_option("--config", a.config_file, "YAML file of parameters (see `v4r config`, detect.*)");
  c->add_option("--set", a.sets, "Set one parameter: --set detect.search.max_hypotheses=20 (repeatable)");
  c->add_option("--mesh-scale", a.units.mesh_scale, "Model units to metres: 0.001 for millimetres")->check(CLI::Range(1e-9, 1e9));
  c->add_option("--model-units", a.units.units, "Units of the model file: mm, cm or m")->check(CLI::IsMember({"mm", "cm", "m"}));
  c->add_flag("--progress", a.progress, "Show the template progress line even when stderr is not a terminal");
}

}  // namespace

/// Registers `v4r prepare` and `v4r detect`; when one ran, `exit_code` holds its exit code.
void add_detect_commands(CLI::App& app, int& exit_code) {
  auto pa = std::make_shared<DetectArgs>();
  auto* prepare = app.add_subcommand("prepare", "Build the detector's view templates of a model ahead of time (cached)");
  add_shared(prepare, *pa);
  prepare->add_option("--camera", pa->camera, "Calibration the templates are for (default: the built-in 640x480 camera)");
  prepare->callback([pa, prepare, &exit_code] {
    pa->units.mesh_scale_given = prepare->get_option("--mesh-scale")->count() > 0;
    exit_code = run_prepare(*pa);
  });

  auto da = std::make_shared<DetectArgs>();
  auto* detect = app.add_subcommand("detect", "Find a model in one image without an initial pose; print the verified poses");
  add_shared(detect, *da);
  detect->add_option("--camera", da->camera, "Calibration: OpenCV YAML/XML, ROS camera_info YAML or ViSP XML")->required();
  detect->add_option("--input", da->input, "Image file (8-bit grey or colour)")->required();
  detect->add_flag("--all", da->all, "Also print the hypotheses that failed verification");
  detect->add_option("--colour,--color", da->colour,
                     "Colour of the model's faces, R,G,B in 0..1 (e.g. 0.2,0.6,0.1): regions of it are searched first "
                     "(detect.colour.*); replaces the model's face colours");
  detect->callback([da, detect, &exit_code] {
    da->units.mesh_scale_given = detect->get_option("--mesh-scale")->count() > 0;
    exit_code = run_detect(*da);
  });
}

}  // namespace v4r::app
