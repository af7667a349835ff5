// v4r - robust model-based object tracking. MIT licence.
// `v4r serve`: the tracker as a TCP service (docs/protocol.md).
// Compiled only once apps/v4r links v4r::server (until then the header is not on the path).
#if __has_include("v4r/server/server.hpp")
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "v4r/detection/detector_params.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/io/config_io.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/pipeline/params.hpp"
#include "v4r/server/server.hpp"
#include "scene_inputs.hpp"
#include "scene_setup.hpp"
#if V4R_HAVE_ROS2
#include "v4r/ros2/image_source.hpp"
#include "v4r/ros2/ros2_publisher.hpp"
#endif

namespace v4r::app {

namespace {

/// \brief Command-line arguments of `v4r serve`.
struct ServeArgs {
  server::ServerOptions opt;
  std::string camera_path;
  std::string scene_path;  ///< --scene: every camera (and object) of a scene file
  int port = 5757;
  int http_port = -1;
  std::string config_file;
  std::vector<std::string> sets;
  bool fps_given = false;
  bool ros2 = false;  ///< --ros2: publish on ROS 2 topics (DDS)
  int ros2_domain = 0;
  std::string ros2_namespace = "/v4r";
  std::string ros2_frame_id = "camera_optical_frame";
};

/// `--scene S.yaml`: the scene file's cameras with their inputs, its reference frame and its
/// objects (an object without init_pose is searched for, as one added without SetPose).
Expected<server::ServeScene> load_serve_scene(const std::string& path) {
  auto file = io::load_scene_file(path);
  if (!file) return file.error();
  for (const io::SceneCameraSpec& c : file->cameras)
    if (c.calibration.width <= 0 || c.calibration.height <= 0)
      return c.at.error(fmt::format("camera '{}': its calibration gives no image size (image_width, image_height), "
                                    "which `v4r serve --scene` needs",
                                    c.name));
  auto inputs = open_scene_inputs(*file, "v4r serve --scene");
  if (!inputs) return inputs.error();
  auto setup = build_scene(*file, false);  // models, start poses; errors name the line and field
  if (!setup) return setup.error();
  server::ServeScene sc;
  sc.cameras.assign(setup->scene.cameras().begin(), setup->scene.cameras().end());
  sc.inputs = std::move(*inputs);
  sc.reference_frame = file->reference_frame;
  for (std::size_t i = 0; i < setup->scene.objects().size(); ++i) {
    const scene::Object& o = setup->scene.objects()[i];
    sc.objects.push_back(server::StartObject{o.name, o.model, o.T_ref_obj, o.status != scene::TrackStatus::kSearching,
                                             file->objects[i].tag});
  }
  return sc;
}

int run_serve(ServeArgs& a) {
  std::optional<server::ServeScene> scene;
  if (!a.scene_path.empty()) {
    if (!a.opt.input.empty() || !a.camera_path.empty()) {
      fmt::print(stderr, "v4r serve: error: --scene names the cameras and their inputs: give it without --camera "
                         "and --input\n");
      return 1;
    }
    auto s = load_serve_scene(a.scene_path);
    if (!s) {
      fmt::print(stderr, "v4r serve: error: {}\n", s.error().to_string());
      return 1;
    }
    scene = std::move(*s);
  } else if (a.opt.input.empty()) {
    fmt::print(stderr, "v4r serve: error: --input is required (or --scene S.yaml)\n");
    return 1;
  }
  const bool ros2_input = a.opt.input.starts_with("ros2:");
  Expected<geometry::PinholeCamera> cam = make_error("");
#if V4R_HAVE_ROS2
  ros2::register_image_input(a.ros2_domain);
  if (ros2_input && a.camera_path.empty()) {
    fmt::print("v4r serve: waiting for camera_info of {} (DDS domain {})\n", a.opt.input, a.ros2_domain);
    std::fflush(stdout);
    cam = ros2::wait_camera_info(a.opt.input, a.ros2_domain, std::chrono::seconds(30));
  }
#else
  if (ros2_input) {
    fmt::print(stderr, "v4r serve: error: --input {}: this v4r was built without ROS 2 (install cyclonedds-dev and "
                       "cyclonedds-tools, then build again)\n", a.opt.input);
    return 1;
  }
#endif
  if (scene) {
    cam = scene->cameras[0].intrinsics;
  } else if (!a.camera_path.empty()) {
    cam = io::load_camera(a.camera_path);
  } else if (!ros2_input) {
    fmt::print(stderr, "v4r serve: error: --camera is required (except with --input ros2:..., whose camera_info "
                       "is used)\n");
    return 1;
  }
  if (!cam) {
    fmt::print(stderr, "v4r serve: error: {}\n", cam.error().to_string());
    return 1;
  }
  a.opt.camera = *cam;
  a.opt.port = static_cast<std::uint16_t>(a.port);
  // A live camera sets the pace itself: each frame is taken as soon as it arrives (unless --fps).
  const bool live_scene =
      scene && std::any_of(scene->inputs.begin(), scene->inputs.end(), [](const auto& in) { return in->live(); });
  if ((io::is_live_input(a.opt.input) || ros2_input || live_scene) && !a.fps_given) a.opt.fps = 0.0;
  a.opt.http_port = a.http_port;
  if (a.opt.token.empty()) {
    // The token can also come from the environment, where `ps` does not show it.
    if (const char* t = std::getenv("V4R_SERVE_TOKEN")) a.opt.token = t;
  }
  ParamRegistry reg = pipeline::make_registry(a.opt.params);
  // detect.* and search.*: objects without SetPose, and lost ones, are searched for (issue 10).
  detection::add_params(reg, a.opt.detect);
  pipeline::add_search_params(reg, a.opt.search);
  if (!a.config_file.empty()) {
    if (auto r = io::apply_config_file(a.config_file, reg); !r) {
      fmt::print(stderr, "v4r serve: error: {}\n", r.error().to_string());
      return 1;
    }
  }
  for (const std::string& kv : a.sets) {
    const auto eq = kv.find('=');
    auto r = eq == std::string::npos ? Expected<void>(make_error("--set expects key=value, got '" + kv + "'"))
                                     : reg.set(kv.substr(0, eq), kv.substr(eq + 1));
    if (!r) {
      fmt::print(stderr, "v4r serve: error: --set: {}\n", r.error().to_string());
      return 1;
    }
  }
#if V4R_HAVE_ROS2
  std::unique_ptr<ros2::Ros2Publisher> ros2_pub;
  if (a.ros2) {
    auto pub = ros2::Ros2Publisher::create(
        ros2::Ros2Options{.domain = a.ros2_domain, .ns = a.ros2_namespace, .frame_id = a.ros2_frame_id});
    if (!pub) {
      fmt::print(stderr, "v4r serve: error: --ros2: {}\n", pub.error().to_string());
      return 1;
    }
    ros2_pub = std::move(*pub);
    a.opt.frame_observer = [p = ros2_pub.get()](const server::FrameEvents& f) { p->publish(f); };
    fmt::print("v4r serve: ROS 2 (DDS domain {}): {}/<object>/pose, {}/<object>/status, /tf in frame {}\n",
               a.ros2_domain, a.ros2_namespace == "/" ? "" : a.ros2_namespace,
               a.ros2_namespace == "/" ? "" : a.ros2_namespace, a.ros2_frame_id);
  }
#else
  if (a.ros2) {
    fmt::print(stderr, "v4r serve: error: --ros2: this v4r was built without ROS 2 (install cyclonedds-dev and "
                       "cyclonedds-tools, then build again)\n");
    return 1;
  }
#endif
  auto srv = scene ? server::Server::create(a.opt, std::move(*scene)) : server::Server::create(a.opt);
  if (!srv) {
    fmt::print(stderr, "v4r serve: error: {}\n", srv.error().to_string());
    return 1;
  }
  fmt::print("v4r serve: protocol on {}:{}{}{}; input {} at {} fps{}; Ctrl-C stops\n", a.opt.bind, (*srv)->port(),
             a.opt.token.empty() ? "" : " (Auth required)",
             (*srv)->http_port() ? fmt::format(", monitor on http://{}:{}/", a.opt.bind, (*srv)->http_port()) : "",
             a.scene_path.empty() ? a.opt.input : "scene " + a.scene_path, a.opt.fps, a.opt.paused ? ", paused until Start" : "");
  std::fflush(stdout);
  const int rc = (*srv)->run();
  const server::ServerStats st = (*srv)->stats();
  fmt::print("v4r serve: stopped after {} frames, {} connections\n", st.frames, st.connections);
  return rc;
}

}  // namespace

/// Registers `v4r serve`; when it ran, `exit_code` holds its exit code.
void add_serve_command(CLI::App& app, int& exit_code) {
  auto a = std::make_shared<ServeArgs>();
  auto* serve = app.add_subcommand("serve", "Run the tracker as a TCP service (protocol: docs/protocol.md)");
  serve->add_option("--camera", a->camera_path,
                    "Calibration (OpenCV or ROS camera_info YAML); required except with --input ros2:..., whose "
                    "camera_info is used when it is not given");
  serve->add_option("--input", a->opt.input, "Image folder, printf pattern (frames/%06d.png), video, camera /dev/videoN, gst:PIPELINE or ros2:/camera (required unless --scene)");
  serve->add_option("--scene", a->scene_path,
                    "Scene file (docs/scene_file.md): every camera with its input, taken in step, and the objects "
                    "to track from their init_pose; poses are T_ref_obj in its reference_frame (docs/protocol.md)");
  serve->add_option("--fps", a->opt.fps,
                    "Frames per second the input is played at (0: as fast as processed; a live camera: its own rate)")
      ->check(CLI::Range(0.0, 10000.0))
      ->capture_default_str()
      ->each([a](const std::string&) { a->fps_given = true; });
  serve->add_option("--port", a->port, "Protocol port (0: any free port)")->check(CLI::Range(0, 65535))->capture_default_str();
  serve->add_option("--bind", a->opt.bind, "Listening address; anything but loopback requires --token")->capture_default_str();
  serve->add_option("--http", a->http_port, "Port of the monitoring page (/, /stream.mjpg, /status.json)")
      ->check(CLI::Range(0, 65535));
  serve->add_flag("--paused", a->opt.paused, "Hold the input at frame 0 until a client sends Start");
  serve->add_option("--token", a->opt.token,
                    "Clients must send `Auth token=SECRET` first (or set V4R_SERVE_TOKEN, hidden from ps)");
  serve->add_option("--max-clients", a->opt.max_clients, "Most simultaneous protocol clients")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  serve->add_option("--log-file", a->opt.log_file, "CSV written by `Log on` without file=")->capture_default_str();
  serve->add_option("--data-dir", a->opt.data_dirs,
                    "Folder that `AddModel path=` (and .cao load(...)) may read; repeatable; relative paths are taken "
                    "inside the first (default: the folder serve was started in)");
  serve->add_option("--log-dir", a->opt.log_dir,
                    "Folder that `Log on file=` may write (default: none, `file=` is refused)");
  serve->add_option("--cache-dir", a->opt.cache_dir,
                    "Folder of the detector's template cache (default $XDG_CACHE_HOME/v4r or ~/.cache/v4r)");
  serve->add_option("--config", a->config_file, "YAML file of tracker parameters (see `v4r config`)");
  serve->add_option("--set", a->sets, "Set one parameter: --set track.rows=32 (repeatable)");
  serve->add_flag("--ros2", a->ros2,
                  "Publish poses, status and /tf as ROS 2 messages over DDS (Cyclone; CYCLONEDDS_URI applies)");
  serve->add_option("--ros2-domain", a->ros2_domain, "DDS domain id (ROS_DOMAIN_ID)")
      ->check(CLI::Range(0, 232))
      ->capture_default_str();
  serve->add_option("--ros2-namespace", a->ros2_namespace, "ROS namespace of the per-object topics")
      ->capture_default_str();
  serve->add_option("--ros2-frame-id", a->ros2_frame_id, "frame_id of the headers (the camera's optical frame)")
      ->capture_default_str();
  serve->callback([a, &exit_code] { exit_code = run_serve(*a); });
}

}  // namespace v4r::app

#endif  // __has_include("v4r/server/server.hpp")
