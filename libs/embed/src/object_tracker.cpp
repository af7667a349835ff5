// v4r - robust model-based object tracking. MIT licence.
// The C++17 facade (object_tracker.hpp) over SingleObjectTracker.

#include "v4r/embed/object_tracker.hpp"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <filesystem>
#include <optional>
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/io/config_io.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/model/mesh_reader.hpp"
#include "v4r/model/model_scale.hpp"
#include "v4r/pipeline/params.hpp"
#include "v4r/pipeline/tracker.hpp"

namespace v4r::embed {
namespace {

namespace fs = std::filesystem;

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

Expected<std::shared_ptr<const model::Model>> load_model(const std::string& path, double scale) {
  std::error_code ec;
  if (path.empty()) return make_error("no model file given");
  if (!fs::is_regular_file(path, ec)) return make_error(path, 0, 0, "model file not found");
  Expected<model::Model> m = make_error("");
  if (lower_extension(path) == ".cao") {
    m = model::load_cao(path);
  } else {
    model::MeshImportOptions mo;
    mo.scale = scale;
    m = model::load_mesh(path, mo);
    scale = 1.0;  // applied on import
  }
  if (!m) return m.error();
  if (m->lines().empty() && m->arcs().empty()) return make_error(path, 0, 0, "model has no edges to track");
  if (scale != 1.0) {
    auto s = model::scaled(*m, scale);
    if (!s) return s.error();
    m = std::move(*s);
  }
  return std::make_shared<const model::Model>(std::move(*m));
}

geometry::SE3 to_se3(const Pose& p) {
  const Eigen::Quaterniond q(p.q[0], p.q[1], p.q[2], p.q[3]);
  return geometry::SE3(q, Eigen::Vector3d(p.t[0], p.t[1], p.t[2]));
}

}  // namespace

struct ObjectTracker::Impl {
  std::shared_ptr<const model::Model> model;
  pipeline::CycleParams params;
  std::optional<geometry::PinholeCamera> camera;
  std::optional<pipeline::SingleObjectTracker> tracker;
  std::optional<geometry::SE3> pose;  ///< last pose set or tracked (kept across a camera change)
  bool pose_pending = false;          ///< set_pose() not yet applied to the tracker
  cv::Mat bgr, grey;                  ///< conversion buffers (reused)
};

ObjectTracker::ObjectTracker(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ObjectTracker::~ObjectTracker() = default;

std::unique_ptr<ObjectTracker> ObjectTracker::create(const TrackerOptions& options, std::string& error) {
  if (!(options.model_scale > 0.0) || !std::isfinite(options.model_scale)) {
    error = fmt::format("model scale must be a positive number, got {}", options.model_scale);
    return nullptr;
  }
  auto impl = std::make_unique<Impl>();
  auto m = load_model(options.model, options.model_scale);
  if (!m) {
    error = m.error().to_string();
    return nullptr;
  }
  impl->model = *m;
  if (!options.config.empty()) {
    ParamRegistry reg = pipeline::make_registry(impl->params);
    if (auto r = io::apply_config_file(options.config, reg); !r) {
      error = r.error().to_string();
      return nullptr;
    }
  }
  return std::unique_ptr<ObjectTracker>(new ObjectTracker(std::move(impl)));
}

bool ObjectTracker::set_camera(const CameraIntrinsics& c, std::string& error) {
  if (c.width <= 0 || c.height <= 0 || !(c.fx > 0.0) || !(c.fy > 0.0) || !std::isfinite(c.cx) || !std::isfinite(c.cy)) {
    error = fmt::format("invalid camera: {}x{} px, fx {} fy {} (size and focal lengths must be positive)", c.width,
                        c.height, c.fx, c.fy);
    return false;
  }
  geometry::PinholeCamera cam;
  cam.width = c.width;
  cam.height = c.height;
  cam.fx = c.fx;
  cam.fy = c.fy;
  cam.cx = c.cx;
  cam.cy = c.cy;
  cam.dist = c.dist;
  Impl& d = *impl_;
  if (d.camera && d.camera->width == cam.width && d.camera->height == cam.height && d.camera->fx == cam.fx &&
      d.camera->fy == cam.fy && d.camera->cx == cam.cx && d.camera->cy == cam.cy && d.camera->dist == cam.dist)
    return true;
  d.camera = cam;
  d.tracker.emplace(d.model, cam, d.params);
  d.pose_pending = d.pose.has_value();
  return true;
}

bool ObjectTracker::has_camera() const { return impl_->camera.has_value(); }

void ObjectTracker::set_pose(const Pose& T_cam_obj) {
  impl_->pose = to_se3(T_cam_obj);
  impl_->pose_pending = true;
}

bool ObjectTracker::has_pose() const { return impl_->pose.has_value(); }

bool ObjectTracker::track(const std::uint8_t* data, int width, int height, int step, PixelFormat format,
                          double stamp_s, TrackOutput& out, std::string& error) {
  Impl& d = *impl_;
  if (!d.tracker) {
    error = "no camera calibration yet";
    return false;
  }
  if (!d.pose) {
    error = "no initial pose yet";
    return false;
  }
  if (data == nullptr || width != d.camera->width || height != d.camera->height) {
    error = fmt::format("image is {}x{} but the camera calibration is {}x{}", width, height, d.camera->width,
                        d.camera->height);
    return false;
  }
  const int channels = format == PixelFormat::kMono8 ? 1 : 3;
  if (step < width * channels) {
    error = fmt::format("image step {} is less than {} bytes per row", step, width * channels);
    return false;
  }
  if (d.pose_pending) {
    d.tracker->set_pose(*d.pose);
    d.pose_pending = false;
  }
  // OpenCV headers over the caller's buffer (no copy); conversions into reused buffers.
  const cv::Mat in(height, width, channels == 1 ? CV_8UC1 : CV_8UC3, const_cast<std::uint8_t*>(data),
                   static_cast<std::size_t>(step));
  image::ColourView colour;
  image::ImageView grey;
  switch (format) {
    case PixelFormat::kMono8:
      grey = io::as_view(in);
      break;
    case PixelFormat::kBgr8:
      cv::cvtColor(in, d.grey, cv::COLOR_BGR2GRAY);
      grey = io::as_view(d.grey);
      colour = io::as_colour_view(in);
      break;
    case PixelFormat::kRgb8:
      cv::cvtColor(in, d.bgr, cv::COLOR_RGB2BGR);
      cv::cvtColor(d.bgr, d.grey, cv::COLOR_BGR2GRAY);
      grey = io::as_view(d.grey);
      colour = io::as_colour_view(d.bgr);
      break;
  }
  const pipeline::FrameResult r = d.tracker->track(grey, colour, stamp_s);
  d.pose = r.T_cam_obj;
  const Eigen::Vector3d& t = r.T_cam_obj.translation();
  const Eigen::Quaterniond& q = r.T_cam_obj.quaternion();
  out.pose.t = {t.x(), t.y(), t.z()};
  out.pose.q = {q.w(), q.x(), q.y(), q.z()};
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) out.covariance[static_cast<std::size_t>(i * 6 + j)] = r.covariance(i, j);
  out.status = scene::to_string(r.report.status);
  out.quality = std::isfinite(r.report.quality) ? std::clamp(r.report.quality, 0.0, 1.0) : 0.0;
  out.cycle_ms = r.cycle_ms;
  return true;
}

bool parse_pose(const std::string& text, Pose& out, std::string& error) {
  std::istringstream in(text);
  std::array<double, 6> v{};
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!(in >> v[i]) || !std::isfinite(v[i])) {
      error = fmt::format("pose '{}': expected 6 numbers \"tx ty tz rx ry rz\" (metres, radians), number {} is missing "
                          "or not a number",
                          text, i + 1);
      return false;
    }
  }
  std::string rest;
  if (in >> rest) {
    error = fmt::format("pose '{}': expected 6 numbers, found more ('{}')", text, rest);
    return false;
  }
  out = pose_from_rvec({v[0], v[1], v[2]}, {v[3], v[4], v[5]});
  return true;
}

Pose pose_from_rvec(const std::array<double, 3>& t, const std::array<double, 3>& rvec) {
  const geometry::SE3 T = geometry::SE3::from_rvec(Eigen::Vector3d(t[0], t[1], t[2]),
                                                   Eigen::Vector3d(rvec[0], rvec[1], rvec[2]));
  Pose p;
  p.t = t;
  const Eigen::Quaterniond& q = T.quaternion();
  p.q = {q.w(), q.x(), q.y(), q.z()};
  return p;
}

}  // namespace v4r::embed
