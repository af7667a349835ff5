// v4r - robust model-based object tracking. MIT licence.
// The v4r command line: track, render, demo, bench, inspect-model.
#include <cctype>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <opencv2/imgproc.hpp>

#include "app.hpp"
#if V4R_HAVE_ROS2
#include "v4r/ros2/image_source.hpp"
#endif
#include "inspect.hpp"
#include "plausibility.hpp"
#include "progress.hpp"
#include "scene_cost.hpp"
#include "scene_track.hpp"
#include "v4r/geometry/look_at.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/io/config_io.hpp"
#include "v4r/detection/detector_params.hpp"
#include "v4r/detection/tag_spec.hpp"
#include "v4r/pipeline/params.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/model/model_colour.hpp"
#include "v4r/pipeline/evaluation.hpp"
#include "v4r/synth/conditions.hpp"
#include "v4r/synth/renderer.hpp"

namespace fs = std::filesystem;
using namespace v4r;

namespace v4r::app {
void add_serve_command(CLI::App& app, int& exit_code);  // serve.cpp
void add_detect_commands(CLI::App& app, int& exit_code);  // detect.cpp
}  // namespace v4r::app

namespace {

struct RenderArgs {
  std::string model = "ship", out, camera;
  app::ModelUnitsArgs units;
  bool force = false;
  int frames = 120;
  double speed = 1.0, distance = 0.6, azimuth = -0.6, elevation = 0.75, noise = 2.0;
  unsigned seed = 7;
  bool grey = false;
  bool noise_given = false;
  std::vector<std::string> conditions{"regular"};
};

/// A model as render and bench use it: loaded (built-in, .cao or mesh, scaled), with the bytes
/// of its file and the name it gets in a rendered sequence.
struct ModelInput {
  std::shared_ptr<const model::Model> model;
  std::string file_name, bytes;
  double scale = 1.0;
};

Expected<ModelInput> model_input(const RenderArgs& a) {
  auto scale = app::model_scale(a.units);
  if (!scale) return scale.error();
  auto m = app::load_model(a.model, *scale);
  if (!m) return m.error();
  ModelInput in;
  in.model = *m;
  in.scale = *scale;
  if (auto text = app::builtin_model_text(a.model); text && !fs::exists(a.model)) {
    in.bytes = *text;
    in.file_name = "model.cao";
    return in;
  }
  std::ifstream f(a.model, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  in.bytes = ss.str();
  std::string ext = fs::path(a.model).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  in.file_name = "model" + ext;
  return in;
}

/// A folder render may write into: never the file system's root; an existing folder only when it
/// is empty or --force is given.
Expected<void> check_output_folder(const std::string& out, bool force) {
  std::error_code ec;
  const fs::path p = fs::weakly_canonical(fs::absolute(out, ec), ec);
  if (out.empty() || p == p.root_path())
    return make_error(out, 0, 0, "refusing to write a sequence into the file system's root; give a folder");
  if (!fs::exists(p, ec)) return {};
  if (!fs::is_directory(p, ec)) return make_error(out, 0, 0, "exists and is not a folder");
  if (!force && !fs::is_empty(p, ec))
    return make_error(out, 0, 0, "the folder is not empty; choose a new one or add --force to write into it");
  return {};
}

Expected<geometry::PinholeCamera> render_camera(const RenderArgs& a) {
  if (a.camera.empty()) return synth::default_camera();
  return io::load_camera(a.camera);
}

std::vector<geometry::SE3> trajectory_for(const RenderArgs& a) {
  synth::TrajectorySpec spec;
  spec.frames = a.frames;
  spec.speed = a.speed;
  spec.T0 = geometry::look_at(a.distance, a.azimuth, a.elevation);
  for (const std::string& c : a.conditions)
    if (auto cond = synth::parse_condition(c)) spec = synth::trajectory_spec_for(*cond, spec);
  return synth::make_trajectory(spec);
}

synth::RenderOptions render_options_for(const RenderArgs& a) {
  synth::RenderOptions ro;
  ro.seed = a.seed;
  ro.colour = !a.grey;
  for (const std::string& c : a.conditions)
    if (auto cond = synth::parse_condition(c)) ro = synth::options_for(*cond, ro);
  if (a.noise_given) ro.noise_sigma = a.noise;  // an explicit --noise wins over the conditions
  return ro;
}

int cmd_render(const RenderArgs& a) {
  if (auto ok = check_output_folder(a.out, a.force); !ok) {
    fmt::print(stderr, "v4r render: error: {}\n", ok.error().to_string());
    return 1;
  }
  auto in = model_input(a);
  if (!in) {
    fmt::print(stderr, "v4r render: error: {}\n", in.error().to_string());
    return 1;
  }
  auto cam = render_camera(a);
  if (!cam) {
    fmt::print(stderr, "v4r render: error: {}\n", cam.error().to_string());
    return 1;
  }
  const auto traj = trajectory_for(a);
  for (const std::string& w : app::check_model_size(*in->model, a.model)) fmt::print(stderr, "v4r render: warning: {}\n", w);
  for (const std::string& w : app::check_projection(*in->model, *cam, traj.front()))
    fmt::print(stderr, "v4r render: warning: {}\n", w);
  app::ProgressLine bar(app::stderr_is_terminal(), a.frames);
  auto r = synth::write_sequence(a.out, *in->model, in->file_name, in->bytes, *cam, traj, render_options_for(a),
                                 [&bar](std::size_t done, std::size_t) { bar.update(static_cast<int>(done)); });
  bar.finish();
  if (!r) {
    fmt::print(stderr, "v4r render: error: {}\n", r.error().to_string());
    return 1;
  }
  fmt::print("rendered {} frames into {} (frames/, gt.csv, camera.yaml, init_pose.txt, {})\n", a.frames, a.out,
             in->file_name);
  if (in->scale != 1.0) fmt::print("track it with --model {} --mesh-scale {}\n", (fs::path(a.out) / in->file_name).string(), in->scale);
  return 0;
}

int cmd_demo(const std::string& out) {
  RenderArgs ra;
  ra.model = "ship";
  ra.out = (fs::path(out) / "sequence").string();
  ra.force = true;  // the demo's own folder: a second run replaces it
  fmt::print("v4r demo: rendering the ship-section mockup ({} frames) into {}\n", ra.frames, ra.out);
  if (int rc = cmd_render(ra); rc != 0) return rc;
  app::TrackOptions to;
  to.model_path = (fs::path(ra.out) / "model.cao").string();
  to.camera_path = (fs::path(ra.out) / "camera.yaml").string();
  to.input = (fs::path(ra.out) / "frames").string();
  to.init_pose_file = (fs::path(ra.out) / "init_pose.txt").string();
  to.output_csv = (fs::path(out) / "poses.csv").string();
  to.overlay = (fs::path(out) / "overlay.avi").string();
  to.gt_csv = (fs::path(ra.out) / "gt.csv").string();
  fmt::print("v4r demo: tracking\n");
  const int rc = app::cmd_track(to);
  if (rc == 0) fmt::print("v4r demo: poses in {}, overlay video in {}\n", to.output_csv, to.overlay);
  return rc;
}

int cmd_bench(const RenderArgs& a, int repeat, double budget_ms, const pipeline::CycleParams& base) {
  auto in = model_input(a);
  if (!in) {
    fmt::print(stderr, "v4r bench: error: {}\n", in.error().to_string());
    return 1;
  }
  const std::shared_ptr<const model::Model> model = in->model;
  const geometry::PinholeCamera cam = synth::default_camera();
  const auto traj = trajectory_for(a);
  synth::RenderOptions ro = render_options_for(a);
  ro.colour = false;
  ro.cycle_frames = a.frames;
  synth::Renderer renderer(cam, ro);
  renderer.set_scene_reference(*model, traj);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < a.frames; ++i) frames.push_back(renderer.render(*model, traj[i], i, i > 0 ? &traj[i - 1] : nullptr));
  app::TrackSummary s;
  std::int64_t overruns = 0;
  for (int r = 0; r < repeat; ++r) {
    pipeline::CycleParams params = base;
    params.budget.cycle_ms = budget_ms;
    pipeline::SingleObjectTracker tracker(model, cam, params);
    tracker.set_pose(traj[0]);
    for (int i = 0; i < a.frames; ++i) {
      const auto res = tracker.track(io::as_view(frames[i]));
      if (r == repeat - 1) s.poses.push_back(res.T_cam_obj);
      s.cycle_ms.push_back(res.cycle_ms);
      s.visibility_ms.push_back(res.visibility_ms);
      s.track_ms.push_back(res.track_ms);
      s.solve_ms.push_back(res.solve_ms);
      s.features_used.push_back(res.report.features_used);
      s.features_visible.push_back(res.report.features_visible);
      s.features_found.push_back(res.report.features_found);
      s.junctions_used.push_back(res.report.junctions_used);
      if (res.report.status == scene::TrackStatus::kLost) ++s.lost;
      ++s.frames;
      overruns = res.overruns;
    }
  }
  const auto median = [](const std::vector<int>& v) {
    return pipeline::percentiles(std::vector<double>(v.begin(), v.end())).median;
  };
  fmt::print("v4r bench: model {} ({}) at {}x{}, {} frames x {} runs, {} overruns\n", a.model,
             fmt::join(a.conditions, ","), cam.width, cam.height, a.frames, repeat, overruns);
  fmt::print("features per frame (median): {} edges and circles visible, {} found, {} junctions used, {} observations "
             "used by the pose solve\n",
             median(s.features_visible), median(s.features_found), median(s.junctions_used), median(s.features_used));
  app::print_report(s, &traj);
  return 0;
}

/// `v4r bench --cameras N --objects M`: the cost of a scene against one camera and one object.
int cmd_bench_scene(const RenderArgs& a, int repeat, double budget_ms, int cameras, int objects, int threads,
                    const pipeline::CycleParams& params) {
  auto in = model_input(a);
  if (!in) {
    fmt::print(stderr, "v4r bench: error: {}\n", in.error().to_string());
    return 1;
  }
  app::SceneCostInput sc;
  sc.model = in->model;
  sc.camera = synth::default_camera();
  sc.trajectory = trajectory_for(a);
  sc.render = render_options_for(a);
  sc.render.colour = false;
  sc.render.cycle_frames = a.frames;
  sc.cameras = cameras;
  sc.objects = objects;
  sc.repeat = repeat;
  sc.budget_ms = budget_ms;
  sc.params = params;
  sc.threads = threads;
  return app::run_scene_cost(sc);
}

/// Applies --config FILE and then each --set key=value to the cycle parameters (and the
/// detector's, detect.*, when given; else they are checked and dropped until the cycle uses them).
Expected<void> configure(pipeline::CycleParams& params, const std::string& config_file,
                         const std::vector<std::string>& sets, detection::DetectorParams* detect = nullptr,
                         pipeline::ObjectSearchParams* search = nullptr) {
  ParamRegistry reg = pipeline::make_registry(params);
  detection::DetectorParams unused;
  detection::add_params(reg, detect ? *detect : unused);
  pipeline::ObjectSearchParams unused_search;
  pipeline::add_search_params(reg, search ? *search : unused_search);
  if (!config_file.empty()) {
    auto r = io::apply_config_file(config_file, reg);
    if (!r) return r;
  }
  for (const std::string& kv : sets) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos) return make_error(fmt::format("--set expects key=value, got '{}'", kv));
    auto r = reg.set(kv.substr(0, eq), kv.substr(eq + 1));
    if (!r) {
      Error e = r.error();
      e.file = "--set";
      return Unexpected{std::move(e)};
    }
  }
  return {};
}

/// --mesh-scale and --model-units on a subcommand that reads a model.
void add_units_options(CLI::App* cmd, app::ModelUnitsArgs& u) {
  cmd->add_option("--mesh-scale", u.mesh_scale, "Model units to metres: 0.001 for millimetres (meshes and .cao)")
      ->check(CLI::Range(1e-9, 1e9));
  cmd->add_option("--model-units", u.units, "Units of the model file: mm, cm or m (the readable --mesh-scale)")
      ->check(CLI::IsMember({"mm", "cm", "m"}));
}

/// `v4r track --scene S.yaml --output-dir D [--overlay DIR]`.
void add_scene_track_options(CLI::App* track, app::SceneTrackOptions& o) {
  track->add_option("--scene", o.scene_path,
                    "Scene file (YAML): cameras (calibration, input, T_ref_cam) and objects (model, init_pose); "
                    "replaces --model, --camera, --input and the initial pose");
  track->add_option("--output-dir", o.output_dir, "With --scene: folder of the pose CSVs, one <object>.csv per object");
}

/// The options `v4r track` needs: --scene with --output-dir, or --model, --camera, --input and
/// --output. Returns what is wrong, or nothing.
std::string check_track_usage(CLI::App* track) {
  const auto given = [track](const char* name) { return track->get_option(name)->count() > 0; };
  if (given("--scene")) {
    for (const char* o : {"--model", "--camera", "--input", "--init-pose", "--init-pose-file", "--output", "--gt", "--tag",
                          "--colour"})
      if (given(o)) return fmt::format("{} cannot be combined with --scene (the scene file describes it)", o);
    if (!given("--output-dir")) return "--scene needs --output-dir D (one D/<object>.csv per object)";
    return {};
  }
  if (given("--output-dir")) return "--output-dir goes with --scene; a single object is written with --output";
  for (const char* o : {"--model", "--camera", "--input", "--output"})
    if (!given(o)) return fmt::format("{} is required (or --scene S.yaml --output-dir D)", o);
  return {};
}

constexpr const char* kModelHelp = "box, ship, flange, section, sponge, a .cao file or a mesh (.obj, .ply, .stl)";

}  // namespace

int main(int argc, char** argv) {
#if V4R_HAVE_ROS2
  {
    // `--input ros2:/camera` (ROS 2 images over DDS), in the domain ROS_DOMAIN_ID (default 0);
    // `v4r serve` registers it again with --ros2-domain.
    const char* d = std::getenv("ROS_DOMAIN_ID");
    const int domain = d ? std::atoi(d) : 0;
    v4r::ros2::register_image_input(domain >= 0 && domain <= 232 ? domain : 0);
  }
#endif
  try {
    CLI::App app{"v4r: real-time 6-DoF tracking of CAD-modelled objects"};
    app.require_subcommand(1);
    app.set_version_flag("--version", std::string("v4r ") + V4R_VERSION);
    app.footer("`v4r help COMMAND` or `v4r COMMAND --help` for a command's options.");

    app::TrackOptions to;
    app::ModelUnitsArgs track_units;
    std::string init_pose_str;
    bool no_warnings = false, progress = false;
    auto* track = app.add_subcommand("track", "Track an object through an image sequence or video");
    track->add_option("--model", to.model_path, kModelHelp);
    track->add_option("--camera", to.camera_path, "Calibration: OpenCV YAML/XML, ROS camera_info YAML or ViSP XML");
    track->add_option("--input", to.input, "Image folder, printf pattern (frames/%06d.png), video, camera /dev/videoN, gst:PIPELINE or ros2:/camera");
    auto* ipf = track->add_option("--init-pose-file", to.init_pose_file, "File with 'tx ty tz rx ry rz' (T_cam_obj)");
    auto* ip = track->add_option("--init-pose", init_pose_str, "Initial T_cam_obj: \"tx ty tz rx ry rz\" (m, rad)");
    ipf->excludes(ip);
    std::string tag_str;
    track->add_option("--tag", tag_str,
                      "An AprilTag on the object to start from: family:id:size_m:\"tx ty tz rx ry rz\" (e.g. "
                      "tag36h11:0:0.08:\"0 0 0.05 3.1416 0 0\"): size_m = edge of the tag's black square (m); the pose "
                      "is T_obj_tag (m, rad), tag frame x right, y down as printed, z into the surface. Used while the "
                      "object is searched; tracking itself is markerless");
    track->add_option("--output,--out", to.output_csv, "Pose CSV to write");
    app::SceneTrackOptions sto;
    add_scene_track_options(track, sto);
    track->add_option("--overlay", to.overlay, "Overlay video (.avi/.mp4) or folder of PNGs; with --scene a folder, DIR/<camera>/ per camera");
    track->add_option("--gt", to.gt_csv, "Ground-truth CSV: print accuracy");
    track->add_option("--fps", to.fps,
                      "Input frame rate for the time stamps (default: the video's own rate, else 1 / filter.frame_interval)")
        ->check(CLI::Range(1e-3, 10000.0));
    track->add_flag("--file-times", to.file_times, "Time stamps from the image files' modification times");
    add_units_options(track, track_units);
    track->add_flag("--no-warnings", no_warnings, "Skip the plausibility checks of pose, units and framing");
    track->add_flag("--progress", progress, "Show the progress line even when stderr is not a terminal");
    std::string config_file;
    std::vector<std::string> sets;
    track->add_option("--config", config_file, "YAML file of tracker parameters (see `v4r config`)");
    track->add_option("--set", sets, "Set one parameter: --set track.rows=32 (repeatable)");
    std::string track_colour;
    track->add_option("--colour,--color", track_colour,
                      "Colour of the model's faces, R,G,B in 0..1 (e.g. 0.2,0.6,0.1): the object search looks for "
                      "regions of it first (detect.colour.*); replaces the model's face colours");
    track->add_option("--cache-dir", to.cache_dir,
                      "Folder of the detector's template cache (default $XDG_CACHE_HOME/v4r or ~/.cache/v4r)");

    RenderArgs ra;
    auto* render = app.add_subcommand("render", "Render a synthetic sequence with ground truth");
    render->add_option("--model", ra.model, kModelHelp)->capture_default_str();
    add_units_options(render, ra.units);
    render->add_option("--output,--out", ra.out, "Output folder (new or empty, see --force)")->required();
    render->add_flag("--force", ra.force, "Write into a folder that is not empty");
    render->add_option("--frames", ra.frames, "Number of frames")->check(CLI::Range(1, 100000))->capture_default_str();
    render->add_option("--speed", ra.speed, "Motion speed factor")->check(CLI::Range(0.0, 100.0))->capture_default_str();
    render->add_option("--distance", ra.distance, "Initial distance, m")->check(CLI::Range(0.05, 100.0))->capture_default_str();
    auto* noise_opt = render->add_option("--noise", ra.noise, "Sensor noise sigma, grey levels (default: the condition's)")
                          ->check(CLI::Range(0.0, 100.0));
    render->add_option("--condition", ra.conditions, "Conditions, comma separated: " + fmt::format("{}", fmt::join(synth::condition_names(), ", ")))
        ->delimiter(',')
        ->check(CLI::IsMember(synth::condition_names()));
    render->add_option("--azimuth", ra.azimuth, "Initial view azimuth, rad")->capture_default_str();
    render->add_option("--elevation", ra.elevation, "Initial view elevation, rad")->check(CLI::Range(-1.5, 1.5))->capture_default_str();
    render->add_option("--seed", ra.seed, "Random seed")->capture_default_str();
    render->add_option("--camera", ra.camera, "Calibration file (default: built-in 640x480)");
    render->add_flag("--grey", ra.grey, "Render grey images");

    std::string demo_out = "build/demo";
    auto* demo = app.add_subcommand("demo", "Render the ship mockup, track it, print accuracy and timing");
    demo->add_option("--output,--out", demo_out, "Output folder")->capture_default_str();

    RenderArgs ba;
    int repeat = 5;
    auto* bench = app.add_subcommand("bench", "Benchmark the vision cycle on a rendered sequence (in memory)");
    bench->add_option("--model", ba.model, kModelHelp)->capture_default_str();
    add_units_options(bench, ba.units);
    bench->add_option("--condition", ba.conditions, "Rendering conditions (see render)")
        ->delimiter(',')
        ->check(CLI::IsMember(synth::condition_names()));
    double bench_budget = 0.0;
    bench->add_option("--budget", bench_budget, "Cycle time budget, ms (0: none)")->check(CLI::Range(0.0, 1000.0));
    bench->add_option("--frames", ba.frames, "Frames")->check(CLI::Range(2, 100000))->capture_default_str();
    bench->add_option("--repeat", repeat, "Runs over the sequence")->check(CLI::Range(1, 1000))->capture_default_str();
    int bench_cameras = 1, bench_objects = 1;
    bench->add_option("--cameras", bench_cameras,
                      "Cameras (a stereo partner 12 cm right, toed in 5 deg, then more): the cost against camera 0 alone")
        ->check(CLI::Range(1, 4))
        ->capture_default_str();
    bench->add_option("--objects", bench_objects, "Copies of the model side by side: the cost against one object alone")
        ->check(CLI::Range(1, 4))
        ->capture_default_str();
    std::string bench_config;
    std::vector<std::string> bench_sets;
    bench->add_option("--config", bench_config, "YAML file of tracker parameters (see `v4r config`)");
    bench->add_option("--set", bench_sets, "Set one parameter: --set samples.enabled=false (repeatable)");
    int bench_threads = 1;
    bench->add_option("--threads", bench_threads,
                      "With --cameras/--objects: also run the cycle over all of them on this many threads (cycle.threads)")
        ->check(CLI::Range(1, 16))
        ->capture_default_str();

    std::string cfg_in;
    std::vector<std::string> cfg_sets;
    auto* config = app.add_subcommand("config", "Print the effective tracker configuration (YAML, with units and ranges)");
    config->add_option("--config", cfg_in, "Start from this YAML file");
    config->add_option("--set", cfg_sets, "Set one parameter: --set track.rows=32 (repeatable)");

    int serve_exit = 0;
    app::add_serve_command(app, serve_exit);
    auto* serve = app.get_subcommand("serve");
    int detect_exit = 0;
    app::add_detect_commands(app, detect_exit);
    auto* prepare_cmd = app.get_subcommand("prepare");
    auto* detect_cmd = app.get_subcommand("detect");

    std::string inspect_path;
    app::ModelUnitsArgs inspect_units;
    bool inspect_verbose = false;
    auto* inspect = app.add_subcommand("inspect-model", "Load a model and print its features, size and units");
    auto* inspect_pos = inspect->add_option("model", inspect_path, kModelHelp);
    auto* inspect_opt = inspect->add_option("--model", inspect_path, kModelHelp);
    inspect_pos->excludes(inspect_opt);
    add_units_options(inspect, inspect_units);
    inspect->add_flag("--verbose,-v", inspect_verbose, "List every face, line and circle");
    model::CaoReadOptions cao_options;
    inspect->add_option("--max-off-plane", cao_options.max_off_plane,
                        "Refuse .cao faces whose points are farther than this fraction of the face's diameter from "
                        "its least-squares plane (smaller offsets above 0.1 % are accepted with a warning)")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();

    std::string help_topic;
    auto* help = app.add_subcommand("help", "Print the help of a command: v4r help track");
    help->add_option("command", help_topic, "Command name");

    CLI11_PARSE(app, argc, argv);
    ra.noise_given = noise_opt->count() > 0;
    ra.units.mesh_scale_given = render->get_option("--mesh-scale")->count() > 0;
    ba.units.mesh_scale_given = bench->get_option("--mesh-scale")->count() > 0;
    track_units.mesh_scale_given = track->get_option("--mesh-scale")->count() > 0;
    inspect_units.mesh_scale_given = inspect->get_option("--mesh-scale")->count() > 0;

    if (*help) {
      if (help_topic.empty()) {
        fmt::print("{}", app.help());
        return 0;
      }
      CLI::App* sub = nullptr;
      try {
        sub = app.get_subcommand(help_topic);
      } catch (const CLI::OptionNotFound&) {
        sub = nullptr;
      }
      if (sub == nullptr || sub == help) {
        fmt::print(stderr, "v4r help: error: no command '{}' (track, render, demo, bench, config, serve, inspect-model, prepare, detect)\n",
                   help_topic);
        return 1;
      }
      fmt::print("{}", sub->help());
      return 0;
    }
    if (*track) {
      if (auto usage = check_track_usage(track); !usage.empty()) {
        fmt::print(stderr, "v4r track: error: {}\nRun with --help for more information.\n", usage);
        return 106;  // CLI11's code for a missing required option
      }
      if (!sto.scene_path.empty()) {
        sto.warnings = !no_warnings;
        if (progress) sto.progress = 1;
        sto.fps = to.fps;
        sto.overlay_dir = to.overlay;
        sto.quiet = to.quiet;
        sto.cache_dir = to.cache_dir;
        if (auto c = configure(sto.params, config_file, sets, &sto.detect, &sto.search); !c) {
          fmt::print(stderr, "v4r track: error: {}\n", c.error().to_string());
          return 1;
        }
        return app::cmd_track_scene(sto);
      }
      if (track->get_option("--tag")->count() > 0) {
        auto t = detection::parse_tag_spec(tag_str, "--tag");
        if (!t) {
          fmt::print(stderr, "v4r track: error: {}\n", t.error().to_string());
          return 1;
        }
        to.tag = *t;
      }
      if (!init_pose_str.empty()) {
        auto p = io::parse_pose_numbers(init_pose_str, "--init-pose");
        if (!p) {
          fmt::print(stderr, "v4r track: error: {}\n", p.error().to_string());
          return 1;
        }
        to.init_pose = *p;
      }
      if (!track_colour.empty()) {
        auto c = model::parse_colour(track_colour, "--colour");
        if (!c) {
          fmt::print(stderr, "v4r track: error: {}\n", c.error().to_string());
          return 1;
        }
        to.colour = *c;
      }
      auto scale = app::model_scale(track_units);
      if (!scale) {
        fmt::print(stderr, "v4r track: error: {}\n", scale.error().to_string());
        return 1;
      }
      to.mesh_scale = *scale;
      to.warnings = !no_warnings;
      if (progress) to.progress = 1;
      if (auto c = configure(to.params, config_file, sets, &to.detect, &to.search); !c) {
        fmt::print(stderr, "v4r track: error: {}\n", c.error().to_string());
        return 1;
      }
      return app::cmd_track(to);
    }
    if (*config) {
      pipeline::CycleParams params;
      detection::DetectorParams dparams;
      pipeline::ObjectSearchParams sparams;
      if (auto c = configure(params, cfg_in, cfg_sets, &dparams, &sparams); !c) {
        fmt::print(stderr, "v4r config: error: {}\n", c.error().to_string());
        return 1;
      }
      ParamRegistry reg = pipeline::make_registry(params);
      detection::add_params(reg, dparams);
      pipeline::add_search_params(reg, sparams);
      fmt::print("# v4r tracker configuration (v4r track --config FILE; detect.*: v4r detect / prepare and the "
                 "search of track and serve; search.*: when an object is searched for)\n{}",
                 reg.to_yaml());
      return 0;
    }
    if (*prepare_cmd || *detect_cmd) return detect_exit;
    if (*serve) return serve_exit;
    if (*render) return cmd_render(ra);
    if (*demo) return cmd_demo(demo_out);
    if (*bench) {
      pipeline::CycleParams bench_params;
      if (auto c = configure(bench_params, bench_config, bench_sets); !c) {
        fmt::print(stderr, "v4r bench: error: {}\n", c.error().to_string());
        return 2;
      }
      if (bench_cameras > 1 || bench_objects > 1)
        return cmd_bench_scene(ba, repeat, bench_budget, bench_cameras, bench_objects, bench_threads, bench_params);
      return cmd_bench(ba, repeat, bench_budget, bench_params);
    }
    if (*inspect) {
      if (inspect_path.empty()) {
        fmt::print(stderr, "v4r inspect-model: error: give a model: v4r inspect-model FILE (or --model FILE)\n");
        return 1;
      }
      auto scale = app::model_scale(inspect_units);
      if (!scale) {
        fmt::print(stderr, "v4r inspect-model: error: {}\n", scale.error().to_string());
        return 1;
      }
      return app::cmd_inspect(inspect_path, *scale, inspect_verbose, cao_options);
    }
    return 0;
  } catch (const std::exception& e) {
    fmt::print(stderr, "v4r: internal error: {}\n", e.what());
    return 2;
  }
}
