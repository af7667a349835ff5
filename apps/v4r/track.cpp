// v4r - robust model-based object tracking. MIT licence.
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "app.hpp"
#include "v4r/io/camera_io.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/model/mesh_reader.hpp"
#include "v4r/pipeline/evaluation.hpp"
#include "v4r/viz/overlay.hpp"

namespace v4r::app {

namespace fs = std::filesystem;

Expected<std::shared_ptr<const model::Model>> load_model(const std::string& path, double mesh_scale,
                                                         const model::CaoReadOptions& cao, std::vector<Error>* warnings) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (!fs::exists(path)) return make_error(path, 0, 0, "model file not found");
  Expected<model::Model> m = make_error("");
  if (ext == ".cao") {
    m = model::load_cao(path, cao, warnings);
  } else if (ext == ".obj" || ext == ".ply" || ext == ".stl" || ext == ".off" || ext == ".dae" || ext == ".fbx" ||
             ext == ".3ds" || ext == ".gltf" || ext == ".glb") {
    model::MeshImportOptions mo;
    mo.scale = mesh_scale;
    m = model::load_mesh(path, mo);
  } else {
    return make_error(path, 0, 0, fmt::format("unsupported model format '{}' (supported: .cao, .obj, .ply, .stl)", ext));
  }
  if (!m) return m.error();
  if (m->lines().empty() && m->arcs().empty()) return make_error(path, 0, 0, "model has no edges to track");
  return std::shared_ptr<const model::Model>(std::make_shared<model::Model>(std::move(*m)));
}

namespace {

/// Writes overlay frames into a video (.avi, .mp4, .mkv) or a folder of PNGs.
class OverlayWriter {
 public:
  Expected<void> open(const std::string& path, cv::Size size) {
    path_ = path;
    const std::string ext = fs::path(path).extension().string();
    if (ext == ".avi" || ext == ".mp4" || ext == ".mkv") {
      const int fourcc = ext == ".mp4" ? cv::VideoWriter::fourcc('m', 'p', '4', 'v') : cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
      if (fs::path(path).has_parent_path()) fs::create_directories(fs::path(path).parent_path());
      if (!video_.open(path, fourcc, 30.0, size)) return make_error(path, 0, 0, "cannot open overlay video for writing");
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

}  // namespace

Expected<TrackSummary> run_track(const TrackOptions& opt) {
  auto model = load_model(opt.model_path, opt.mesh_scale);
  if (!model) return model.error();
  auto cam = io::load_camera(opt.camera_path);
  if (!cam) return cam.error();
  geometry::SE3 init;
  if (opt.init_pose) {
    init = *opt.init_pose;
  } else if (!opt.init_pose_file.empty()) {
    auto p = io::load_pose_file(opt.init_pose_file);
    if (!p) return p.error();
    init = *p;
  } else {
    return make_error("an initial pose is needed: --init-pose-file FILE or --init-pose \"tx ty tz rx ry rz\"");
  }
  if (init.translation().z() <= 0.0)
    return make_error("the initial pose puts the object behind the camera (tz <= 0)");
  auto source = io::FrameSource::open(opt.input);
  if (!source) return source.error();

  std::FILE* csv = nullptr;
  if (!opt.output_csv.empty()) {
    if (fs::path(opt.output_csv).has_parent_path()) {
      std::error_code ec;
      fs::create_directories(fs::path(opt.output_csv).parent_path(), ec);
    }
    csv = std::fopen(opt.output_csv.c_str(), "w");
    if (!csv) return make_error(opt.output_csv, 0, 0, "cannot open output CSV for writing");
    std::fprintf(csv,
                 "frame,tx,ty,tz,qw,qx,qy,qz,cycle_ms,status,quality,features_visible,features_found,features_used,"
                 "outliers,rms_px,lines_used,circle_points_used,junctions_used,degrade_level,"
                 "f_tx,f_ty,f_tz,f_qw,f_qx,f_qy,f_qz,vx,vy,vz,wx,wy,wz\n");
  }
  struct Closer {
    std::FILE* f;
    ~Closer() {
      if (f) std::fclose(f);
    }
  } closer{csv};

  pipeline::SingleObjectTracker tracker(*model, *cam, opt.params);
  tracker.set_pose(init);
  OverlayWriter overlay;
  TrackSummary s;
  cv::Mat frame, grey;
  for (int i = 0;; ++i) {
    auto more = (*source)->next(frame);
    if (!more) return more.error();
    if (!*more) break;
    if (frame.cols != cam->width || frame.rows != cam->height)
      return make_error((*source)->current_name(), 0, 0,
                        fmt::format("image is {}x{} but the camera calibration {} is {}x{}", frame.cols, frame.rows,
                                    opt.camera_path, cam->width, cam->height));
    if (frame.channels() == 3) {
      cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
    } else if (frame.channels() == 4) {
      cv::cvtColor(frame, grey, cv::COLOR_BGRA2GRAY);
    } else {
      grey = frame;
    }
    const double stamp = opt.fps > 0 ? i / opt.fps : -1.0;
    const pipeline::FrameResult r = tracker.track(io::as_view(grey), io::as_colour_view(frame), stamp);
    s.poses.push_back(r.T_cam_obj);
    s.cycle_ms.push_back(r.cycle_ms);
    s.visibility_ms.push_back(r.visibility_ms);
    s.track_ms.push_back(r.track_ms);
    s.solve_ms.push_back(r.solve_ms);
    s.features_used.push_back(r.report.features_used);
    if (r.report.status == scene::TrackStatus::kLost) ++s.lost;
    if (r.report.status == scene::TrackStatus::kDegraded) ++s.degraded;
    if (csv) {
      const auto& q = r.T_cam_obj.quaternion();
      const auto& t = r.T_cam_obj.translation();
      const auto& fq = r.T_cam_obj_filtered.quaternion();
      const auto& ft = r.T_cam_obj_filtered.translation();
      const auto& v = r.velocity;
      std::fprintf(csv,
                   "%d,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.4f,%s,%.3f,%d,%d,%d,%d,%.3f,%d,%d,%d,%d,"
                   "%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n",
                   i, t.x(), t.y(), t.z(), q.w(), q.x(), q.y(), q.z(), r.cycle_ms, scene::to_string(r.report.status),
                   r.report.quality, r.report.features_visible, r.report.features_found, r.report.features_used,
                   r.report.outliers, r.report.rms_px, r.report.lines_used, r.report.circle_points_used,
                   r.report.junctions_used, r.degrade_level, ft.x(), ft.y(), ft.z(), fq.w(), fq.x(), fq.y(), fq.z(),
                   v[0], v[1], v[2], v[3], v[4], v[5]);
    }
    if (!opt.overlay.empty()) {
      cv::Mat vis;
      if (frame.channels() == 3) {
        vis = frame.clone();
      } else {
        cv::cvtColor(grey, vis, cv::COLOR_GRAY2BGR);
      }
      if (i == 0) {
        auto o = overlay.open(opt.overlay, vis.size());
        if (!o) return o.error();
      }
      pipeline::CycleReport rep;
      rep.frame = i;
      rep.cycle_ms = r.cycle_ms;
      rep.objects.push_back(r.report);
      viz::draw_overlay(vis, tracker.scene(), tracker.cycle(), 0, rep);
      auto w = overlay.write(vis, i);
      if (!w) return w.error();
    }
    ++s.frames;
  }
  if (s.frames == 0) return make_error(opt.input, 0, 0, "the input holds no frames");
  return s;
}

void print_report(const TrackSummary& s, const std::vector<geometry::SE3>* truth) {
  fmt::print("frames {}  lost {}  degraded {}\n", s.frames, s.lost, s.degraded);
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
  auto s = run_track(opt);
  if (!s) {
    fmt::print(stderr, "v4r track: error: {}\n", s.error().to_string());
    return 1;
  }
  std::vector<geometry::SE3> truth;
  if (!opt.gt_csv.empty()) {
    auto rows = io::load_pose_csv(opt.gt_csv);
    if (!rows) {
      fmt::print(stderr, "v4r track: error: {}\n", rows.error().to_string());
      return 1;
    }
    for (const auto& r : *rows) truth.push_back(r.T_cam_obj);
  }
  if (!opt.quiet) print_report(*s, opt.gt_csv.empty() ? nullptr : &truth);
  return 0;
}

}  // namespace v4r::app
