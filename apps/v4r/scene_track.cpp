// v4r - robust model-based object tracking. MIT licence.
// `v4r track --scene S.yaml --output-dir D`: every camera and object of a scene file, one cycle
// per frame over all cameras, one pose CSV per object.
#include "scene_track.hpp"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "plausibility.hpp"
#include "pose_csv.hpp"
#include "progress.hpp"
#include "scene_inputs.hpp"
#include "scene_setup.hpp"
#include "templates.hpp"
#include "v4r/detection/tag_start.hpp"
#include "v4r/detection/template_cache.hpp"
#include "v4r/geometry/se3_jacobians.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/io/scene_file.hpp"
#include "v4r/pipeline/evaluation.hpp"
#include "v4r/viz/overlay.hpp"

namespace v4r::app {

namespace fs = std::filesystem;

namespace {

/// One pose CSV, closed when it goes.
struct CsvFile {
  std::FILE* f = nullptr;
  CsvFile() = default;
  CsvFile(const CsvFile&) = delete;
  CsvFile& operator=(const CsvFile&) = delete;
  ~CsvFile() {
    if (f) std::fclose(f);
  }
};

/// The inputs of the cameras, read in step.
struct CameraInput {
  std::unique_ptr<io::FrameSource> source;
  cv::Mat frame, grey;
};

/// Opens every camera's input (open_scene_inputs).
Expected<std::vector<CameraInput>> open_inputs(const io::SceneFile& file) {
  auto sources = open_scene_inputs(file, "v4r track --scene");
  if (!sources) return sources.error();
  std::vector<CameraInput> inputs(sources->size());
  for (std::size_t c = 0; c < inputs.size(); ++c) inputs[c].source = std::move((*sources)[c]);
  return inputs;
}

/// Reads frame k of every camera; false at the common end; an error naming the inputs that ended
/// when the others go on.
Expected<bool> read_in_step(const io::SceneFile& file, std::vector<CameraInput>& inputs, int k) {
  std::vector<bool> ended(inputs.size(), false);
  std::size_t n_ended = 0;
  for (std::size_t c = 0; c < inputs.size(); ++c) {
    auto more = inputs[c].source->next(inputs[c].frame);
    if (!more) return more.error();
    ended[c] = !*more;
    if (ended[c]) ++n_ended;
  }
  if (n_ended == 0) return true;
  if (n_ended == inputs.size()) return false;
  for (std::size_t c = 0; c < inputs.size(); ++c)
    if (ended[c])
      return file.cameras[c].input_at.error(
          fmt::format("camera '{}' has {} frames but the other cameras have more: the cameras' frames are taken in "
                      "step, their inputs must be of equal length",
                      file.cameras[c].name, k));
  return false;
}

}  // namespace

Expected<SceneTrackSummary> run_scene_track(const SceneTrackOptions& opt) {
  auto file = io::load_scene_file(opt.scene_path);
  if (!file) return file.error();
  if (file->objects.empty())
    return file->objects_at.error("no objects: `v4r track --scene` needs at least one object to track");
  if (!opt.search.enabled)
    for (const io::SceneObjectSpec& o : file->objects)
      if (o.tag) return o.tag_at.error("the tag is used by the search, and search.enabled is false");
  auto inputs = open_inputs(*file);
  if (!inputs) return inputs.error();
  // Frame 0 of every camera first: a calibration without the image size takes its camera's.
  auto first = read_in_step(*file, *inputs, 0);
  if (!first) return first.error();
  if (!*first) return file->cameras[0].input_at.error("the input holds no frames");
  for (std::size_t c = 0; c < inputs->size(); ++c)
    if (file->cameras[c].calibration.width == 0) {
      file->cameras[c].calibration.width = (*inputs)[c].frame.cols;
      file->cameras[c].calibration.height = (*inputs)[c].frame.rows;
    }
  auto setup = build_scene(*file, opt.warnings);
  if (!setup) return setup.error();
  scene::Scene& sc = setup->scene;

  std::error_code ec;
  fs::create_directories(opt.output_dir, ec);
  if (ec) return make_error(opt.output_dir, 0, 0, "cannot create the output folder: " + ec.message());
  std::vector<CsvFile> csv(file->objects.size());
  SceneTrackSummary s;
  for (std::size_t o = 0; o < file->objects.size(); ++o) {
    const std::string path = (fs::path(opt.output_dir) / (file->objects[o].name + ".csv")).string();
    csv[o].f = std::fopen(path.c_str(), "w");
    if (!csv[o].f) return make_error(path, 0, 0, "cannot open the pose CSV for writing");
    std::fputs(kPoseCsvHeader, csv[o].f);
    s.csv_paths.push_back(path);
  }
  s.objects.resize(file->objects.size());
  for (std::size_t o = 0; o < file->objects.size(); ++o) s.objects[o].name = file->objects[o].name;
  for (const io::SceneCameraSpec& c : file->cameras) s.cameras.push_back(c.name);
  if (!opt.overlay_dir.empty())
    for (const io::SceneCameraSpec& c : file->cameras) {
      fs::create_directories(fs::path(opt.overlay_dir) / c.name, ec);
      if (ec) return make_error((fs::path(opt.overlay_dir) / c.name).string(), 0, 0, "cannot create the overlay folder");
    }

  const double fps = opt.fps > 0.0 ? opt.fps : 1.0 / opt.params.frame_interval_s;
  pipeline::VisionCycle cycle(opt.params);
  // The search (issue 10), set up for an object when it first needs it: from frame 0 without
  // init_pose, else when it is first lost (building templates takes seconds).
  std::optional<pipeline::ObjectSearch> search;
  std::vector<char> searchable(sc.objects().size(), 0);
  const auto make_searchable = [&](std::size_t o) -> Expected<void> {
    if (!search) search.emplace(opt.params, opt.search, opt.detect);
    auto ts = templates_for(*sc.objects()[o].model, sc.cameras()[0].intrinsics, opt.detect, opt.cache_dir, opt.quiet,
                            fmt::format(" of '{}'", sc.objects()[o].name));
    if (!ts) return ts.error();
    search->add_object(sc, o, *ts);
    if (const io::SceneObjectSpec& spec = file->objects[o]; spec.tag) {
      // `tag:` as --tag: the object's AprilTag starts its search in camera 0.
      auto tag = detection::TagStart::create(*spec.tag, sc.cameras()[0].intrinsics, opt.search.tag);
      if (!tag) return spec.tag_at.error(tag.error().to_string());
      search->set_tag_start(o, std::move(*tag));
    }
    searchable[o] = 1;
    return {};
  };
  std::vector<pipeline::ObjectReport> reports(sc.objects().size());
  std::vector<pipeline::CameraImage> images(file->cameras.size());
  const bool progress = opt.progress > 0 || (opt.progress < 0 && stderr_is_terminal());
  ProgressLine bar(progress && !opt.quiet, (*inputs)[0].source->size_hint());
  std::vector<std::string>& warnings = setup->warnings;
  cv::Mat vis;
  for (int k = 0;; ++k) {
    if (k > 0) {
      auto more = read_in_step(*file, *inputs, k);
      if (!more) return more.error();
      if (!*more) break;
    }
    for (std::size_t c = 0; c < inputs->size(); ++c) {
      CameraInput& in = (*inputs)[c];
      const io::SceneCameraSpec& spec = file->cameras[c];
      const scene::Camera& cam2 = sc.cameras()[c];
      if (in.frame.cols != cam2.intrinsics.width || in.frame.rows != cam2.intrinsics.height)
        return make_error(in.source->current_name(), 0, 0,
                          fmt::format("image is {}x{} but the calibration {} of camera '{}' is {}x{}", in.frame.cols,
                                      in.frame.rows, spec.calibration_path, spec.name, cam2.intrinsics.width,
                                      cam2.intrinsics.height));
      if (in.frame.channels() == 3) {
        cv::cvtColor(in.frame, in.grey, cv::COLOR_BGR2GRAY);
      } else if (in.frame.channels() == 4) {
        cv::cvtColor(in.frame, in.grey, cv::COLOR_BGRA2GRAY);
      } else {
        in.grey = in.frame;
      }
      images[c] = pipeline::CameraImage{io::as_view(in.grey), io::as_colour_view(in.frame)};
    }
    if (k == 0) {
      if (opt.warnings)
        for (std::size_t c = 0; c < sc.cameras().size(); ++c)
          for (const scene::Object& o : sc.objects())
            for (auto& w : check_projection(*o.model, sc.cameras()[c].intrinsics,
                                            sc.cameras()[c].T_ref_cam.inverse() * o.T_ref_obj))
              warnings.push_back(fmt::format("{} in camera '{}': {}", o.name, sc.cameras()[c].name, w));
      if (!opt.quiet)
        for (const std::string& w : warnings) fmt::print(stderr, "v4r track: warning: {}\n", w);
      s.warnings = warnings.size();
    }
    const double stamp = k / fps;
    if (opt.search.enabled)
      for (std::size_t o = 0; o < sc.objects().size(); ++o)
        if (!searchable[o] && sc.objects()[o].status == scene::TrackStatus::kSearching)
          if (auto e = make_searchable(o); !e) return e.error();
    const pipeline::CycleReport& rep = cycle.process(sc, images, stamp);
    double cycle_ms = rep.cycle_ms;
    for (std::size_t o = 0; o < sc.objects().size(); ++o) reports[o] = rep.objects[o];
    if (opt.search.enabled) {
      for (std::size_t o = 0; o < sc.objects().size(); ++o)
        if (!searchable[o] && rep.objects[o].status == scene::TrackStatus::kLost)
          if (auto e = make_searchable(o); !e) return e.error();
      if (search) {
        const auto found = search->update(sc, images, rep.stamp_s);  // (the cycle's stamp: a missing one filled in)
        for (std::size_t o = 0; o < found.size(); ++o) {
          cycle_ms += found[o].search_ms;
          const scene::Object& obj = sc.objects()[o];
          if (found[o].locked) {  // found and confirmed on this frame: the pose of the search
            reports[o].evidence = obj.evidence;
            reports[o].quality = obj.quality;
          }
          reports[o].status = obj.status;
        }
      }
    }
    s.cycle_ms.push_back(cycle_ms);
    for (std::size_t o = 0; o < sc.objects().size(); ++o) {
      const scene::Object& obj = sc.objects()[o];
      PoseCsvRow row;
      row.frame = k;
      row.pose = obj.T_ref_obj;
      row.filtered = obj.T_ref_obj_filtered;
      row.velocity = obj.velocity;
      row.covariance = geometry::translation_rotation_covariance(obj.T_ref_obj, obj.covariance);
      row.cycle_ms = cycle_ms;
      row.features_used = features_used(obj);
      row.degrade_level = rep.degrade_level;
      row.stamp_s = stamp;
      row.report = &reports[o];
      write_pose_csv_row(csv[o].f, row);
      SceneTrackSummary::ObjectSummary& os = s.objects[o];
      os.poses.push_back(obj.T_ref_obj);
      if (reports[o].status == scene::TrackStatus::kLost) ++os.lost;
      if (reports[o].status == scene::TrackStatus::kDegraded) ++os.degraded;
      if (reports[o].status == scene::TrackStatus::kSearching) ++os.searching;
    }
    if (!opt.overlay_dir.empty()) {
      for (std::size_t c = 0; c < inputs->size(); ++c) {
        const CameraInput& in = (*inputs)[c];
        if (in.frame.channels() == 3) {
          in.frame.copyTo(vis);
        } else {
          cv::cvtColor(in.grey, vis, cv::COLOR_GRAY2BGR);
        }
        viz::draw_overlay(vis, sc, cycle, c, rep);  // (the cycle's status: searching objects show none)
        const std::string f = (fs::path(opt.overlay_dir) / file->cameras[c].name / fmt::format("{:06d}.png", k)).string();
        if (!cv::imwrite(f, vis)) return make_error(f, 0, 0, "cannot write overlay image");
      }
    }
    ++s.frames;
    int lost_now = 0;
    for (const auto& os : s.objects) lost_now += os.lost;
    bar.update(s.frames, lost_now);
  }
  bar.finish();
  return s;
}

int cmd_track_scene(const SceneTrackOptions& opt) {
  auto s = run_scene_track(opt);
  if (!s) {
    fmt::print(stderr, "v4r track: error: {}\n", s.error().to_string());
    return 1;
  }
  bool all_lost = false;
  if (!opt.quiet) {
    fmt::print("frames {}  cameras {} ({})\n", s->frames, s->cameras.size(), fmt::join(s->cameras, ", "));
    const auto c = pipeline::percentiles(s->cycle_ms);
    fmt::print("cycle over all cameras and objects (ms): median {:.3f}  p99 {:.3f}  max {:.3f}\n", c.median, c.p99, c.max);
  }
  for (std::size_t o = 0; o < s->objects.size(); ++o) {
    const auto& os = s->objects[o];
    if (!opt.quiet)
      fmt::print("{}: lost {}  degraded {}  searching {}  -> {}\n", os.name, os.lost, os.degraded, os.searching,
                 s->csv_paths[o]);
    if (os.lost + os.searching == s->frames) {
      fmt::print(stderr, "v4r track: error: object '{}' was {} on every frame ({} of {}){}\n", os.name,
                 os.searching > 0 ? "lost or searched" : "lost", os.lost + os.searching, s->frames,
                 s->warnings > 0 ? "; see the warnings above"
                                 : "; check its init_pose, units, the cameras' T_ref_cam and the view range (detect.views.*)");
      all_lost = true;
    }
  }
  if (!opt.quiet && !opt.overlay_dir.empty()) fmt::print("wrote {}/<camera>/ (overlays)\n", opt.overlay_dir);
  return all_lost ? 3 : 0;
}

}  // namespace v4r::app
