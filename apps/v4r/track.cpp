// v4r - robust model-based object tracking. MIT licence.
#include <cstdio>
#include <filesystem>
#include <optional>
#include <fstream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "app.hpp"
#include "plausibility.hpp"
#include "pose_csv.hpp"
#include "progress.hpp"
#include "templates.hpp"
#include "v4r/detection/tag_start.hpp"
#include "v4r/detection/template_cache.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/model/mesh_reader.hpp"
#include "v4r/pipeline/evaluation.hpp"
#include "v4r/viz/overlay.hpp"

namespace v4r::app {

namespace fs = std::filesystem;

namespace {

/// Writes overlay frames into a video (.avi, .mp4, .mkv) or a folder of PNGs.
class OverlayWriter {
 public:
  Expected<void> open(const std::string& path, cv::Size size, double fps) {
    path_ = path;
    const std::string ext = fs::path(path).extension().string();
    if (ext == ".avi" || ext == ".mp4" || ext == ".mkv") {
      const int fourcc = ext == ".mp4" ? cv::VideoWriter::fourcc('m', 'p', '4', 'v') : cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
      if (fs::path(path).has_parent_path()) fs::create_directories(fs::path(path).parent_path());
      if (!video_.open(path, fourcc, fps, size)) return make_error(path, 0, 0, "cannot open overlay video for writing");
      return {};
    }
    std::error_code ec;
    fs::create_directories(path, ec);
    if (ec) return make_error(path, 0, 0, "cannot create overlay folder: " + ec.message());
    folder_ = true;
    return {};
  }
  Expected<void> write(const cv::Mat& img, int frame) {
    if (folder_) {
      const std::string f = (fs::path(path_) / fmt::format("{:06d}.png", frame)).string();
      if (!cv::imwrite(f, img)) return make_error(f, 0, 0, "cannot write overlay image");
    } else {
      video_.write(img);
    }
    return {};
  }

 private:
  std::string path_;
  bool folder_ = false;
  cv::VideoWriter video_;
};

/// How frames are stamped: the text says where the times come from.
struct Timing {
  double fps = 0.0;  ///< frames per second, or 0 for file or capture times
  bool file_times = false;
  bool capture_times = false;  ///< a live camera: when each frame was grabbed
  std::string source;
};

Timing choose_timing(const TrackOptions& opt, const io::FrameSource& src) {
  if (opt.fps > 0.0) return {opt.fps, false, false, "--fps"};
  if (opt.file_times) return {0.0, true, false, "image file times"};
  if (src.live()) return {0.0, false, true, "capture times"};
  if (src.nominal_fps() > 0.0) return {src.nominal_fps(), false, false, "the video's frame rate"};
  return {1.0 / opt.params.frame_interval_s, false, false, "filter.frame_interval"};
}

/// Lets the tracker search for the object (issue 10): the detector's templates for this model and
/// camera, from the cache or built (a few seconds, once per model, camera and view range).
Expected<void> enable_search(pipeline::SingleObjectTracker& tracker, const TrackOptions& opt,
                             const model::Model& model, const geometry::PinholeCamera& cam) {
  auto ts = templates_for(model, cam, opt.detect, opt.cache_dir, opt.quiet, "");
  if (!ts) return ts.error();
  tracker.enable_search(*ts, opt.search, opt.detect);
  if (opt.tag) {
    auto tag = detection::TagStart::create(*opt.tag, cam, opt.search.tag);
    if (!tag) {
      Error e = tag.error();
      e.message = "--tag: " + e.message;
      return Unexpected{std::move(e)};
    }
    tracker.set_tag_start(std::move(*tag));
  }
  return {};
}

}  // namespace

Expected<TrackSummary> run_track(const TrackOptions& opt) {
  auto model = load_model(opt.model_path, opt.mesh_scale);
  if (!model) return model.error();
  *model = with_colour(*model, opt.colour);
  auto cam = io::load_camera(opt.camera_path, io::CameraFileOptions{.size_optional = true});
  if (!cam) return cam.error();
  if (opt.tag && !opt.search.enabled) return make_error("--tag is used by the search, and search.enabled is false");
  io::PoseNumbers numbers{};
  std::string pose_source;
  if (opt.init_pose) {
    numbers = *opt.init_pose;
    pose_source = "--init-pose";
  } else if (!opt.init_pose_file.empty()) {
    auto p = io::load_pose_numbers(opt.init_pose_file);
    if (!p) return p.error();
    numbers = *p;
    pose_source = opt.init_pose_file;
  } else if (!opt.search.enabled) {
    return make_error("an initial pose is needed (search.enabled is false): --init-pose-file FILE or --init-pose \"tx ty tz rx ry rz\"");
  }
  const bool have_pose = !pose_source.empty();  // else the object is searched for from frame 0
  const geometry::SE3 init = io::pose_from_numbers(numbers);
  if (have_pose && init.translation().z() <= 0.0)
    return make_error("the initial pose puts the object behind the camera (tz <= 0)");
  std::vector<std::string> warnings;
  if (opt.warnings) {
    for (auto& w : check_model_size(**model, opt.model_path)) warnings.push_back(std::move(w));
    if (have_pose)
      for (auto& w : check_pose(numbers, pose_source)) warnings.push_back(std::move(w));
  }
  auto source = io::FrameSource::open(opt.input);
  if (!source) return source.error();
  const Timing timing = choose_timing(opt, **source);

  std::FILE* csv = nullptr;
  if (!opt.output_csv.empty()) {
    if (fs::path(opt.output_csv).has_parent_path()) {
      std::error_code ec;
      fs::create_directories(fs::path(opt.output_csv).parent_path(), ec);
    }
    csv = std::fopen(opt.output_csv.c_str(), "w");
    if (!csv) return make_error(opt.output_csv, 0, 0, "cannot open output CSV for writing");
    std::fputs(kPoseCsvHeader, csv);
  }
  struct Closer {
    std::FILE* f;
    ~Closer() {
      if (f) std::fclose(f);
    }
  } closer{csv};

  std::optional<pipeline::SingleObjectTracker> tracker;
  OverlayWriter overlay;
  TrackSummary s;
  s.timing = timing.source;
  s.fps = timing.fps;
  const bool progress = opt.progress > 0 || (opt.progress < 0 && stderr_is_terminal());
  ProgressLine bar(progress && !opt.quiet, (*source)->size_hint());
  cv::Mat frame, grey;
  double first_file_time = -1.0;
  bool search_on = false;  // with an initial pose, the search is set up when the object is first lost
  for (int i = 0;; ++i) {
    auto more = (*source)->next(frame);
    if (!more) return more.error();
    if (!*more) break;
    if (i == 0 && cam->width == 0) {  // a calibration without the image size: the first image's
      cam->width = frame.cols;
      cam->height = frame.rows;
    }
    if (frame.cols != cam->width || frame.rows != cam->height)
      return make_error((*source)->current_name(), 0, 0,
                        fmt::format("image is {}x{} but the camera calibration {} is {}x{}", frame.cols, frame.rows,
                                    opt.camera_path, cam->width, cam->height));
    if (i == 0) {
      if (opt.warnings && have_pose)
        for (auto& w : check_projection(**model, *cam, init)) warnings.push_back(std::move(w));
      for (const std::string& w : warnings) fmt::print(stderr, "v4r track: warning: {}\n", w);
      s.warnings = warnings.size();
      tracker.emplace(*model, *cam, opt.params);
      if (have_pose) {
        tracker->set_pose(init);
      } else {
        if (auto e = enable_search(*tracker, opt, **model, *cam); !e) return e.error();
        tracker->start_search();
        search_on = true;
      }
    }
    if (frame.channels() == 3) {
      cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
    } else if (frame.channels() == 4) {
      cv::cvtColor(frame, grey, cv::COLOR_BGRA2GRAY);
    } else {
      grey = frame;
    }
    double stamp = i / timing.fps;
    if (timing.file_times) {
      const double t = (*source)->file_time_s();
      if (t < 0.0) return make_error((*source)->current_name(), 0, 0, "no file time for this frame (--file-times)");
      if (first_file_time < 0.0) first_file_time = t;
      stamp = t - first_file_time;
    } else if (timing.capture_times) {
      const double t = (*source)->capture_time_s();
      if (first_file_time < 0.0) first_file_time = t;
      stamp = t - first_file_time;
    }
    const pipeline::FrameResult r = tracker->track(io::as_view(grey), io::as_colour_view(frame), stamp);
    if (!search_on && opt.search.enabled && r.report.status == scene::TrackStatus::kLost) {
      if (auto e = enable_search(*tracker, opt, **model, *cam); !e) return e.error();
      search_on = true;
    }
    if (r.search.searched) s.search_ms.push_back(r.search.search_ms);
    if (r.report.status == scene::TrackStatus::kSearching) ++s.searching;
    if (r.report.status == scene::TrackStatus::kTracking && s.first_tracking < 0) s.first_tracking = i;
    s.poses.push_back(r.T_cam_obj);
    s.cycle_ms.push_back(r.cycle_ms);
    s.visibility_ms.push_back(r.visibility_ms);
    s.track_ms.push_back(r.track_ms);
    s.solve_ms.push_back(r.solve_ms);
    s.features_used.push_back(r.report.features_used);
    if (r.report.status == scene::TrackStatus::kLost) ++s.lost;
    if (r.report.status == scene::TrackStatus::kDegraded) ++s.degraded;
    if (csv) {
      PoseCsvRow row;
      row.frame = i;
      row.pose = r.T_cam_obj;
      row.filtered = r.T_cam_obj_filtered;
      row.velocity = r.velocity;
      row.covariance = r.covariance;
      row.cycle_ms = r.cycle_ms;
      row.features_used = features_used(tracker->scene().objects()[0]);
      row.degrade_level = r.degrade_level;
      row.stamp_s = stamp;
      row.report = &r.report;
      write_pose_csv_row(csv, row);
    }
    if (!opt.overlay.empty()) {
      cv::Mat vis;
      if (frame.channels() == 3) {
        vis = frame.clone();
      } else {
        cv::cvtColor(grey, vis, cv::COLOR_GRAY2BGR);
      }
      if (i == 0) {
        auto o = overlay.open(opt.overlay, vis.size(), timing.fps > 0.0 ? timing.fps : 1.0 / opt.params.frame_interval_s);
        if (!o) return o.error();
      }
      pipeline::CycleReport rep;
      rep.frame = i;
      rep.cycle_ms = r.cycle_ms;
      rep.objects.push_back(r.report);
      viz::OverlayStyle style;
      style.object_label = fs::path(opt.model_path).stem().string();
      viz::draw_overlay(vis, tracker->scene(), tracker->cycle(), 0, rep, style);
      auto w = overlay.write(vis, i);
      if (!w) return w.error();
    }
    ++s.frames;
    bar.update(s.frames, s.lost);
  }
  bar.finish();
  s.dropped = (*source)->dropped();
  if (s.frames == 0) return make_error(opt.input, 0, 0, "the input holds no frames");
  return s;
}

void print_report(const TrackSummary& s, const std::vector<geometry::SE3>* truth) {
  fmt::print("frames {}  lost {}  degraded {}  searching {}\n", s.frames, s.lost, s.degraded, s.searching);
  if (!s.search_ms.empty()) {
    const auto sp = pipeline::percentiles(s.search_ms);
    fmt::print("search: {} frames, median {:.1f} ms, p99 {:.1f} ms; first tracking frame {}\n", s.search_ms.size(),
               sp.median, sp.p99, s.first_tracking);
  }
  if (truth) {
    const pipeline::AccuracyStats a = pipeline::evaluate(s.poses, *truth);
    fmt::print("accuracy vs ground truth ({} frames):\n", a.frames);
    fmt::print("  translation error  mean {:8.3f} mm   max {:8.3f} mm\n", a.mean_translation_m * 1e3,
               a.max_translation_m * 1e3);
    fmt::print("  rotation error     mean {:8.3f} deg  max {:8.3f} deg\n", a.mean_rotation_deg, a.max_rotation_deg);
    fmt::print("  successes (<5 cm, <5 deg): {}/{}\n", a.successes, a.frames);
  }
  const auto c = pipeline::percentiles(s.cycle_ms), v = pipeline::percentiles(s.visibility_ms),
             t = pipeline::percentiles(s.track_ms), o = pipeline::percentiles(s.solve_ms);
  fmt::print("timing per frame (ms)      median      p99      max\n");
  fmt::print("  cycle                  {:8.3f} {:8.3f} {:8.3f}\n", c.median, c.p99, c.max);
  fmt::print("  visibility+projection  {:8.3f} {:8.3f} {:8.3f}\n", v.median, v.p99, v.max);
  fmt::print("  feature tracking       {:8.3f} {:8.3f} {:8.3f}\n", t.median, t.p99, t.max);
  fmt::print("  pose solve             {:8.3f} {:8.3f} {:8.3f}\n", o.median, o.p99, o.max);
}

int cmd_track(const TrackOptions& opt) {
  // The ground truth is read first: a missing or malformed file is found before the tracking.
  std::vector<geometry::SE3> truth;
  if (!opt.gt_csv.empty()) {
    auto rows = io::load_pose_csv(opt.gt_csv);
    if (!rows) {
      fmt::print(stderr, "v4r track: error: {}\n", rows.error().to_string());
      return 1;
    }
    for (const auto& r : *rows) truth.push_back(r.T_cam_obj);
  }
  auto s = run_track(opt);
  if (!s) {
    fmt::print(stderr, "v4r track: error: {}\n", s.error().to_string());
    return 1;
  }
  if (!opt.quiet) {
    print_report(*s, opt.gt_csv.empty() ? nullptr : &truth);
    const std::string time = s->fps > 0.0 ? fmt::format("{} fps ({})", s->fps, s->timing) : s->timing;
    fmt::print("time stamps: {}\n", time);
    if (s->dropped > 0) fmt::print("live input: {} frames dropped (the tracker took the newest)\n", s->dropped);
    if (!opt.output_csv.empty()) fmt::print("wrote {} ({} rows)\n", opt.output_csv, s->frames);
    if (!opt.overlay.empty()) fmt::print("wrote {} (overlay)\n", opt.overlay);
  }
  if (s->searching + s->lost == s->frames && s->searching > 0) {
    fmt::print(stderr, "v4r track: error: the object was not found on any frame ({} frames searched){}\n",
               s->searching, "; check the model's units, the camera and the view range (detect.views.*)");
    return 3;
  }
  if (s->lost == s->frames) {
    fmt::print(stderr, "v4r track: error: the object was lost on every frame ({} of {}){}\n", s->lost, s->frames,
               s->warnings > 0 ? "; see the warnings above" : "; check the initial pose, the model's units and the camera");
    return 3;
  }
  return 0;
}

}  // namespace v4r::app
