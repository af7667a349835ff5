// v4r - robust model-based object tracking. MIT licence.
#include "v4r/server/tracking_service.hpp"

#include "v4r/geometry/se3_jacobians.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "v4r/core/log.hpp"
#include "v4r/pipeline/params.hpp"
#include "v4r/viz/overlay.hpp"

namespace v4r::server {

namespace code = protocol::code;
using protocol::format_err;
using protocol::format_ok;
using protocol::format_value;

namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

SharedLine shared_line(std::string s) {
  s.push_back('\n');
  return std::make_shared<const std::string>(std::move(s));
}

protocol::TrackStatus to_protocol(scene::TrackStatus s) {
  switch (s) {
    case scene::TrackStatus::kTracking: return protocol::TrackStatus::kTracking;
    case scene::TrackStatus::kDegraded: return protocol::TrackStatus::kDegraded;
    case scene::TrackStatus::kSearching: return protocol::TrackStatus::kSearching;
    default: return protocol::TrackStatus::kLost;
  }
}

Eigen::Vector3d vec(const protocol::Vec3& v) { return {v[0], v[1], v[2]}; }

/// First line of the `Log on` CSV.
constexpr char kLogHeader[] =
    "frame,stamp_s,cycle_ms,visibility_ms,track_ms,solve_ms,degrade_level,features_dropped,objects,"
    "features_visible,features_found,features_used,outliers,observations_found,observations_used,"
    "observation_outliers,overruns\n";

}  // namespace

namespace {
std::vector<std::unique_ptr<io::FrameSource>> one_source(std::unique_ptr<io::FrameSource> source) {
  std::vector<std::unique_ptr<io::FrameSource>> v;
  v.push_back(std::move(source));
  return v;
}
}  // namespace

TrackingService::TrackingService(ServiceOptions opt, std::unique_ptr<io::FrameSource> source)
    : TrackingService(std::move(opt), one_source(std::move(source))) {}

TrackingService::TrackingService(ServiceOptions opt, std::vector<std::unique_ptr<io::FrameSource>> sources)
    : opt_(std::move(opt)),
      sources_(std::move(sources)),
      params_(opt_.params),
      registry_(pipeline::make_registry(params_)),
      cycle_(params_) {
  if (opt_.cameras.empty()) opt_.cameras.push_back(scene::Camera{"camera", opt_.camera, geometry::SE3()});
  for (const scene::Camera& c : opt_.cameras) scene_.add_camera(c);
  frames_in_.resize(opt_.cameras.size());
  greys_.resize(opt_.cameras.size());
  camera_frames_.assign(opt_.cameras.size(), 0);
  camera_alive_.assign(opt_.cameras.size(), 1);
  paused_ = opt_.paused;
  if (opt_.search.enabled)
    search_ = std::make_unique<ServiceSearch>(params_, opt_.search, opt_.detect, opt_.camera, opt_.cache_dir,
                                              opt_.search_hook);
  if (search_)
    for (const StartObject& so : opt_.objects)
      if (so.tag) search_->set_tag(so.name, *so.tag);
  add_start_objects();  // after the search: a start object without a pose is searched for
  if (opt_.object_hook) cycle_.set_object_hook([hook = opt_.object_hook](const scene::Object& o) { hook(o.name); });
}

TrackingService::~TrackingService() {
  stop();
  if (log_) std::fclose(log_);
}

Expected<void> TrackingService::open() {
  if (sources_.size() != opt_.cameras.size() ||
      std::any_of(sources_.begin(), sources_.end(), [](const auto& p) { return p == nullptr; }))
    return make_error("no input");
  auto more = read_in_step();
  if (!more) return more.error();
  if (!*more) return make_error("the input holds no frames");
  have_frame_ = true;
  return {};
}

Expected<bool> TrackingService::read_in_step() {
  // Frame k of every camera's input makes frame k of the scene: one that ends (or fails) while
  // the others go on ends the scene's input.
  std::size_t ended = 0;
  for (std::size_t c = 0; c < sources_.size(); ++c) {
    auto more = sources_[c]->next(frames_in_[c]);
    if (!more || !*more) {
      camera_alive_[c] = 0;
      ++ended;
      if (!more) return more.error();
      continue;
    }
    ++camera_frames_[c];
    const geometry::PinholeCamera& k = opt_.cameras[c].intrinsics;
    const cv::Mat& f = frames_in_[c];
    if (f.cols != k.width || f.rows != k.height)
      return make_error(sources_[c]->current_name(), 0, 0,
                        fmt::format("image is {}x{} but the camera calibration is {}x{}{}", f.cols, f.rows, k.width,
                                    k.height, sources_.size() > 1 ? " (camera '" + opt_.cameras[c].name + "')" : ""));
  }
  if (ended == 0) return true;
  if (ended < sources_.size()) {
    for (std::size_t c = 0; c < sources_.size(); ++c)
      if (!camera_alive_[c])
        return make_error(fmt::format("camera '{}' ended after {} frames while the other cameras go on: the cameras' "
                                      "frames are taken in step",
                                      opt_.cameras[c].name, camera_frames_[c]));
  }
  return false;
}

void TrackingService::add_start_objects() {
  for (const StartObject& so : opt_.objects) {
    ObjectEntry e;
    e.name = so.name;
    e.has_pose = so.has_pose;
    e.pose = so.T_ref_obj;
    objects_.push_back(std::move(e));
    (void)set_model(objects_.back(), so.model, "AddModel");
  }
}

std::vector<protocol::CameraStatus> TrackingService::camera_status() const {
  std::vector<protocol::CameraStatus> v;
  if (opt_.reference_frame.empty()) return v;  // one camera: the protocol as it was
  for (std::size_t c = 0; c < opt_.cameras.size(); ++c)
    v.push_back(protocol::CameraStatus{opt_.cameras[c].name, static_cast<std::uint64_t>(camera_frames_[c]),
                                       camera_alive_[c] != 0});
  return v;
}

void TrackingService::start() {
  if (thread_.joinable()) return;
  thread_ = std::jthread([this](std::stop_token st) { run(st); });
}

void TrackingService::stop() {
  if (!thread_.joinable()) return;
  thread_.request_stop();
  wake_.notify_all();
  thread_.join();
}

namespace {

const char* request_name(const TrackingService::Request& r) {
  if (std::holds_alternative<ModelReady>(r)) return "AddModel";
  return protocol::command_name(std::get<protocol::Command>(r)).data();
}

/// Logs the first faults of a kind and then every 1000th, so that a fault in every frame does
/// not flood the log.
bool worth_logging(std::uint64_t n) { return n <= 10 || n % 1000 == 0; }

}  // namespace

void TrackingService::submit(Request request, ReplyFn done) {
  bool queued = false;
  {
    std::scoped_lock lock(mutex_);
    if (healthy_) {
      queue_.push_back(Pending{std::move(request), std::move(done)});
      queued = true;
    }
  }
  if (!queued) {
    // The tracking thread has stopped: nobody else will answer.
    if (done) done(format_err(request_name(request), code::kInternal, "the tracking thread has stopped (see the server log)"));
    return;
  }
  wake_.notify_one();
}

void TrackingService::run(std::stop_token st) {
  // Top-level handler: whatever escapes the per-frame and per-command handlers below ends this
  // thread cleanly (logged, every waiting command answered) instead of std::terminate.
  try {
    loop(st);
  } catch (const std::exception& e) {
    V4R_LOG_ERROR("v4r serve: the tracking thread stopped: {}", e.what());
    healthy_ = false;
  } catch (...) {
    V4R_LOG_ERROR("v4r serve: the tracking thread stopped: unknown exception");
    healthy_ = false;
  }
  if (healthy_) return;
  std::deque<Pending> left;
  {
    std::scoped_lock lock(mutex_);
    left.swap(queue_);
  }
  for (Pending& p : left) {
    try {
      if (p.done) p.done(format_err(request_name(p.request), code::kInternal, "the tracking thread has stopped"));
    } catch (...) {  // nothing more can be done for this client
    }
  }
}

void TrackingService::loop(std::stop_token st) {
  const bool paced = opt_.fps > 0.0;
  const auto period = paced ? std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / opt_.fps))
                            : Clock::duration::zero();
  due_ = Clock::now();
  bool was_paused = paused_;
  while (!st.stop_requested()) {
    apply_pending();
    if (!have_frame_ && !end_) load_next_frame();
    const bool paused = paused_;
    if (was_paused && !paused) due_ = Clock::now();  // resume without catching up
    was_paused = paused;
    {
      std::unique_lock lock(mutex_);
      if (!have_frame_ || paused) {
        wake_.wait(lock, st, [&] { return !queue_.empty(); });
        continue;
      }
      if (paced && Clock::now() < due_) {
        // Sleep until the frame is due, or until a command arrives (applied first).
        if (wake_.wait_until(lock, st, due_, [&] { return !queue_.empty(); }) || st.stop_requested()) continue;
      }
    }
    const Clock::time_point released = Clock::now();
    frame_cycle(released);
    have_frame_ = false;
    if (paced) {
      due_ += period;
      if (due_ + period < released) due_ = released;  // far behind (slow cycle): do not burst
    }
  }
}

void TrackingService::frame_cycle(Clock::time_point released) {
  // A fault outside any one object's cycle (out of memory, a bug in the event code) costs this
  // frame, not the service: the frame is skipped and the next one is processed as usual.
  try {
    rebuild_models();
    process_frame(released);
  } catch (const std::exception& e) {
    if (worth_logging(++faults_)) V4R_LOG_ERROR("v4r serve: frame {} skipped: {}", next_frame_ - 1, e.what());
  } catch (...) {
    if (worth_logging(++faults_)) V4R_LOG_ERROR("v4r serve: frame {} skipped: unknown exception", next_frame_ - 1);
  }
}

void TrackingService::load_next_frame() {
  auto more = read_in_step();
  if (!more) {
    V4R_LOG_ERROR("v4r serve: input: {}", more.error().to_string());
    end_ = true;
    return;
  }
  if (!*more) {
    end_ = true;
    return;
  }
  have_frame_ = true;
}

void TrackingService::apply_pending() {
  for (;;) {
    Pending p;
    {
      std::scoped_lock lock(mutex_);
      if (queue_.empty()) return;
      p = std::move(queue_.front());
      queue_.pop_front();
    }
    std::string reply;
    try {
      reply = apply(p.request);
    } catch (const std::exception& e) {
      ++faults_;
      V4R_LOG_ERROR("v4r serve: {} failed: {}", request_name(p.request), e.what());
      reply = format_err(request_name(p.request), code::kInternal, e.what());
    }
    if (p.done) p.done(std::move(reply));
  }
}

std::string TrackingService::apply(const Request& r) {
  if (const auto* m = std::get_if<ModelReady>(&r)) {
    ObjectEntry* e = find(m->object);
    if (!e) return format_err("AddModel", code::kUnknownObject, fmt::format("no object '{}'", m->object));
    // A whole model replaces whatever the object had, including features added one by one.
    e->from_features = false;
    e->dirty = false;
    e->features = FeatureModel();
    return set_model(*e, m->model, "AddModel");
  }
  return apply_command(std::get<protocol::Command>(r));
}

std::string TrackingService::apply_command(const protocol::Command& c) {
  return std::visit(Overloaded{[&](const protocol::AddObject& x) { return on(x); },
                               [&](const protocol::RemoveObject& x) { return on(x); },
                               [&](const protocol::AddJunction& x) { return on(x); },
                               [&](const protocol::AddLine& x) { return on(x); },
                               [&](const protocol::AddCircle& x) { return on(x); },
                               [&](const protocol::RemoveFeature& x) { return on(x); },
                               [&](const protocol::SetPose& x) { return on(x); },
                               [&](const protocol::SetParam& x) { return on(x); },
                               [&](const protocol::GetParam& x) { return on(x); },
                               [&](const protocol::ListParams& x) { return on(x); },
                               [&](const protocol::Start& x) { return on(x); },
                               [&](const protocol::Pause& x) { return on(x); },
                               [&](const protocol::Display& x) { return on(x); },
                               [&](const protocol::Log& x) { return on(x); },
                               [&](const auto&) {
                                 return format_err(protocol::command_name(c), code::kInternal,
                                                   "not a command of the tracking service");
                               }},
                    c);
}

TrackingService::ObjectEntry* TrackingService::find(const std::string& name) {
  for (ObjectEntry& e : objects_)
    if (e.name == name) return &e;
  return nullptr;
}

std::string TrackingService::set_model(ObjectEntry& e, std::shared_ptr<const model::Model> m, std::string_view cmd) {
  const long idx = scene_.find_object(e.name);
  if (!m) {
    // No trackable feature left: the object leaves the scene until it has one again.
    if (idx >= 0) scene_.remove_object(static_cast<std::size_t>(idx));
  } else if (idx >= 0) {
    scene_.replace_model(static_cast<std::size_t>(idx), m);  // keeps the tracking state
  } else {
    auto added = scene_.add_object(e.name, m);
    if (!added) return format_err(cmd, code::kInternal, added.error().to_string());
    if (e.has_pose) {
      scene_.set_pose(*added, e.pose);
    } else if (search_) {
      scene_.start_search(*added);  // issue 10: found by the search (ServiceSearch)
    }
  }
  e.model = m;
  e.failed = false;  // a new model is a fresh start
  e.error.clear();
  e.hold_stamp = -1.0;
  count_objects();
  const std::size_t j = m ? m->junctions().size() : 0, l = m ? m->lines().size() : 0, a = m ? m->arcs().size() : 0;
  return format_ok(cmd, fmt::format("object={} junctions={} lines={} circles={}", e.name, j, l, a));
}

std::string TrackingService::on(const protocol::AddObject& c) {
  if (find(c.name)) return format_err("AddObject", code::kExists, fmt::format("object '{}' exists already", c.name));
  if (objects_.size() >= opt_.max_objects)
    return format_err("AddObject", code::kBusy, fmt::format("at most {} objects", opt_.max_objects));
  ObjectEntry e;
  e.name = c.name;
  objects_.push_back(std::move(e));
  return format_ok("AddObject", "name=" + c.name);
}

std::string TrackingService::on(const protocol::RemoveObject& c) {
  auto it = std::find_if(objects_.begin(), objects_.end(), [&](const ObjectEntry& e) { return e.name == c.name; });
  if (it == objects_.end()) return format_err("RemoveObject", code::kUnknownObject, fmt::format("no object '{}'", c.name));
  if (const long idx = scene_.find_object(c.name); idx >= 0) scene_.remove_object(static_cast<std::size_t>(idx));
  objects_.erase(it);
  count_objects();
  return format_ok("RemoveObject", "name=" + c.name);
}

std::string TrackingService::feature_changed(ObjectEntry& e, const char* cmd, const std::string& id, Expected<void> r) {
  if (!r) {
    const std::string& f = r.error().field;
    const std::string_view c = f == "exists" ? code::kExists : f == "not_found" ? code::kUnknownFeature : code::kBadArgument;
    return format_err(cmd, c, r.error().message);
  }
  e.from_features = true;
  e.dirty = true;
  return format_ok(cmd, fmt::format("object={} id={} junctions={} lines={} circles={}", e.name, id,
                                    e.features.junction_count(), e.features.line_count(), e.features.circle_count()));
}

void TrackingService::rebuild_models() {
  for (ObjectEntry& e : objects_) {
    if (!e.dirty) continue;
    e.dirty = false;
    std::shared_ptr<const model::Model> m;
    if (e.features.trackable()) {
      auto built = e.features.build(e.name);
      if (!built) {
        // The features were validated one by one, so this is not expected: keep the last model.
        V4R_LOG_ERROR("v4r serve: object {}: cannot rebuild the model: {}", e.name, built.error().to_string());
        continue;
      }
      m = *built;
    }
    (void)set_model(e, std::move(m), "AddFeature");
  }
}

namespace {
/// Feature commands need an object built feature by feature (or still empty).
const char* feature_conflict(bool has_model, bool from_features) {
  return has_model && !from_features ? "the object's model came from AddModel; features are added to objects built "
                                       "with AddFeature only"
                                     : nullptr;
}
}  // namespace

std::string TrackingService::on(const protocol::AddJunction& c) {
  ObjectEntry* e = find(c.object);
  if (!e) return format_err("AddFeature", code::kUnknownObject, fmt::format("no object '{}'", c.object));
  if (const char* why = feature_conflict(e->model != nullptr, e->from_features))
    return format_err("AddFeature", code::kBadArgument, why);
  if (e->features.junction_count() + e->features.line_count() + e->features.circle_count() >= opt_.max_features)
    return format_err("AddFeature", code::kBusy, fmt::format("at most {} features per object", opt_.max_features));
  auto r = e->features.add_junction(c.id, vec(c.p));
  if (!r) return feature_changed(*e, "AddFeature", c.id, std::move(r));
  e->from_features = true;
  // A junction alone changes nothing the tracker sees: rebuild only when lines use it.
  return format_ok("AddFeature", fmt::format("object={} id={} junctions={} lines={} circles={}", e->name, c.id,
                                             e->features.junction_count(), e->features.line_count(),
                                             e->features.circle_count()));
}

std::string TrackingService::on(const protocol::AddLine& c) {
  ObjectEntry* e = find(c.object);
  if (!e) return format_err("AddFeature", code::kUnknownObject, fmt::format("no object '{}'", c.object));
  if (const char* why = feature_conflict(e->model != nullptr, e->from_features))
    return format_err("AddFeature", code::kBadArgument, why);
  if (e->features.junction_count() + e->features.line_count() + e->features.circle_count() >= opt_.max_features)
    return format_err("AddFeature", code::kBusy, fmt::format("at most {} features per object", opt_.max_features));
  return feature_changed(*e, "AddFeature", c.id, e->features.add_line(c.id, c.from, c.to));
}

std::string TrackingService::on(const protocol::AddCircle& c) {
  ObjectEntry* e = find(c.object);
  if (!e) return format_err("AddFeature", code::kUnknownObject, fmt::format("no object '{}'", c.object));
  if (const char* why = feature_conflict(e->model != nullptr, e->from_features))
    return format_err("AddFeature", code::kBadArgument, why);
  if (e->features.junction_count() + e->features.line_count() + e->features.circle_count() >= opt_.max_features)
    return format_err("AddFeature", code::kBusy, fmt::format("at most {} features per object", opt_.max_features));
  return feature_changed(*e, "AddFeature", c.id, e->features.add_circle(c.id, vec(c.center), vec(c.normal), c.radius));
}

std::string TrackingService::on(const protocol::RemoveFeature& c) {
  ObjectEntry* e = find(c.object);
  if (!e) return format_err("RemoveFeature", code::kUnknownObject, fmt::format("no object '{}'", c.object));
  if (!e->from_features)
    return format_err("RemoveFeature", code::kUnknownFeature,
                      fmt::format("object '{}' has no features added with AddFeature", c.object));
  return feature_changed(*e, "RemoveFeature", c.id, e->features.remove(c.id));
}

std::string TrackingService::on(const protocol::SetPose& c) {
  ObjectEntry* e = find(c.object);
  if (!e) return format_err("SetPose", code::kUnknownObject, fmt::format("no object '{}'", c.object));
  // With a scene (--scene) the pose is T_ref_obj, in a reference frame that need not look along z.
  if (opt_.reference_frame.empty() && c.t[2] <= 0.0)
    return format_err("SetPose", code::kOutOfRange, "the pose puts the object behind the camera (tz <= 0)");
  // Plausibility (the same limits as `v4r track`): a mistake of units, not a pose to track from.
  if (const double angle = vec(c.r).norm(); angle > 2.0 * M_PI)
    return format_err("SetPose", code::kOutOfRange,
                      fmt::format("r=: the rotation vector is {:.1f} rad long, more than 2 pi: degrees? r is radians",
                                  angle));
  if (const double d = vec(c.t).norm(); d > 20.0 || d < 0.01)
    return format_err("SetPose", code::kOutOfRange,
                      fmt::format("t=: the object would be {:.4g} m from the camera (plausible: 0.01 to 20 m): {}", d,
                                  d > 20.0 ? "millimetres? t is metres" : "is t in metres?"));
  e->pose = geometry::SE3::from_rvec(vec(c.t), vec(c.r));
  e->has_pose = true;
  if (e->failed && e->model) {
    // A failed object starts again from the new pose.
    auto added = scene_.add_object(e->name, e->model);
    if (!added) return format_err("SetPose", code::kInternal, added.error().to_string());
    e->failed = false;
    e->error.clear();
    e->hold_stamp = -1.0;
  }
  if (const long idx = scene_.find_object(c.object); idx >= 0) {
    scene_.set_pose(static_cast<std::size_t>(idx), e->pose);
    count_objects();
  }
  return format_ok("SetPose", fmt::format("object={} frame={}", c.object, next_frame_));
}

std::string TrackingService::on(const protocol::SetParam& c) {
  if (!registry_.find(c.name)) {
    auto r = registry_.set(c.name, c.value);  // its message names the nearest parameter
    return format_err("SetParam", code::kUnknownParam, r ? "unknown parameter" : r.error().message);
  }
  if (auto r = registry_.set(c.name, c.value); !r) return format_err("SetParam", code::kBadValue, r.error().message);
  cycle_.set_params(params_);
  auto v = registry_.get(c.name);
  return format_ok("SetParam", fmt::format("name={} value={}", c.name, format_value(v ? *v : c.value)));
}

std::string TrackingService::on(const protocol::GetParam& c) {
  const ParamRegistry::Entry* e = registry_.find(c.name);
  if (!e) {
    auto r = registry_.set(c.name, "");  // for the nearest-name hint only; fails before setting
    return format_err("GetParam", code::kUnknownParam, r ? "unknown parameter" : r.error().message);
  }
  auto v = registry_.get(c.name);
  std::string extra = fmt::format("name={} value={}", c.name, format_value(v ? *v : std::string("?")));
  if (!std::holds_alternative<bool*>(e->field))
    extra += fmt::format(" min={} max={}", protocol::format_number(e->lo), protocol::format_number(e->hi));
  if (!e->unit.empty()) extra += " unit=" + format_value(e->unit);
  if (!e->doc.empty()) extra += " doc=" + format_value(e->doc);
  return format_ok("GetParam", extra);
}

std::string TrackingService::on(const protocol::ListParams&) {
  std::string extra = fmt::format("count={}", registry_.entries().size());
  for (const ParamRegistry::Entry& e : registry_.entries()) {
    auto v = registry_.get(e.name);
    extra += fmt::format(" {}={}", e.name, format_value(v ? *v : std::string("?")));
  }
  return format_ok("ListParams", extra);
}

std::string TrackingService::on(const protocol::Start&) {
  paused_ = false;
  return format_ok("Start", fmt::format("frame={}{}", next_frame_, end_ ? " end=1" : ""));
}

std::string TrackingService::on(const protocol::Pause&) {
  paused_ = true;
  return format_ok("Pause", fmt::format("frame={}", next_frame_));
}

std::string TrackingService::on(const protocol::Display& c) {
  display_ = c.on;
  return format_ok("Display", c.on ? "on" : "off");
}

std::string TrackingService::on(const protocol::Log& c) {
  if (log_) {
    std::fclose(log_);
    log_ = nullptr;
  }
  if (!c.on) return format_ok("Log", "off");
  std::string path = opt_.default_log_file;
  if (!c.file.empty()) {
    // A client names the file: only inside the operator's --log-dir, never through a symlink.
    auto r = opt_.log_dirs.resolve_write(c.file);
    if (!r) return format_err("Log", r.error().field, r.error().message);
    path = r->string();
  }
  const std::string& shown = c.file.empty() ? path : c.file;
  // O_NOFOLLOW: a symlink put in the file's place after the check is not followed.
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) return format_err("Log", code::kIoError, fmt::format("cannot open '{}' for writing", shown));
  // Never truncate anything but an empty file or an earlier cycle log.
  char first[sizeof kLogHeader] = {};
  const ssize_t n = ::read(fd, first, sizeof kLogHeader - 1);
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) ||
      (n > 0 && std::string_view(first, static_cast<std::size_t>(n)) !=
                    std::string_view(kLogHeader).substr(0, static_cast<std::size_t>(n)))) {
    ::close(fd);
    return format_err("Log", code::kIoError, fmt::format("'{}' exists and is not a v4r cycle log: not overwritten", shown));
  }
  if (::ftruncate(fd, 0) != 0 || ::lseek(fd, 0, SEEK_SET) != 0 || !(log_ = ::fdopen(fd, "w"))) {
    ::close(fd);
    return format_err("Log", code::kIoError, fmt::format("cannot open '{}' for writing", shown));
  }
  std::fputs(kLogHeader, log_);
  std::fflush(log_);
  return format_ok("Log", "on file=" + format_value(shown));
}

void TrackingService::process_frame(Clock::time_point released) {
  std::vector<pipeline::CameraImage> images(frames_in_.size());
  for (std::size_t c = 0; c < frames_in_.size(); ++c) {
    const cv::Mat& in = frames_in_[c];
    if (in.channels() == 3) {
      cv::cvtColor(in, greys_[c], cv::COLOR_BGR2GRAY);
    } else if (in.channels() == 4) {
      cv::cvtColor(in, greys_[c], cv::COLOR_BGRA2GRAY);
    } else {
      greys_[c] = in;
    }
    images[c] = pipeline::CameraImage{io::as_view(greys_[c]), io::as_colour_view(in)};
  }
  const io::FrameSource& source = *sources_[0];  // the first camera's input stamps the frame
  const std::int64_t index = next_frame_++;
  // A live camera stamps its frames with their capture time (frames it dropped leave gaps), a
  // frame with a stamp of its own (ROS image) with that; other inputs by their index at the play rate.
  double stamp = opt_.fps > 0.0 ? static_cast<double>(index) / opt_.fps : -1.0;
  if (const double captured = source.capture_time_s(); source.live() && captured >= 0.0) {
    if (first_capture_s_ < 0.0) first_capture_s_ = captured;
    stamp = captured - first_capture_s_;
  }
  if (const double own = source.stamp_s(); own >= 0.0) stamp = own;  // e.g. a ROS image's header
  if (search_) search_->before_cycle(scene_);  // a pose the search's worker found (search.background)
  const pipeline::CycleReport& rep = cycle_.process(scene_, std::span<const pipeline::CameraImage>(images), stamp);
  if (search_) search_->update(scene_, std::span<const pipeline::CameraImage>(images), rep.stamp_s);

  auto ev = std::make_shared<FrameEvents>();
  ev->frame = index;
  ev->stamp_s = rep.stamp_s;
  ev->released = released;
  ev->visibility_ms = rep.visibility_ms;
  ev->track_ms = rep.track_ms;
  ev->solve_ms = rep.solve_ms;
  protocol::SystemStatusEvent& st = ev->status;
  st.frame = static_cast<std::uint64_t>(index);
  st.cycle_ms = rep.cycle_ms;
  st.overruns = static_cast<std::uint64_t>(std::max<std::int64_t>(0, rep.overruns));
  int visible = 0, tracked = 0, found_obs = 0, used_obs = 0, outlier_obs = 0;
  const auto objs = scene_.objects();
  for (std::size_t i = 0; i < objs.size(); ++i) {
    scene::Object& o = objs[i];
    if (o.status == scene::TrackStatus::kUninitialised) continue;
    ++tracked;
    const pipeline::ObjectReport& r = rep.objects[i];
    visible += r.features_visible;
    found_obs += r.features_found;
    used_obs += r.features_used;
    outlier_obs += r.outliers;
    // The protocol counts features (edges, circles), not solver observations: a tracked feature
    // is used, or an outlier when the solver rejected it.
    for (const scene::View& v : o.views) {
      for (const scene::LineFeature& f : v.lines) {
        if (!f.visible || f.ambiguous || f.dropped) continue;
        if (f.status == scene::FeatureStatus::kFound) ++st.features_used;
        if (f.status == scene::FeatureStatus::kOutlier) ++st.outliers;
      }
      for (const scene::ArcFeature& a : v.arcs)
        if (a.visible && !a.dropped && a.status == scene::FeatureStatus::kFound) ++st.features_used;
    }
    protocol::ObjectPoseEvent p;
    p.object = o.name;
    p.frame = static_cast<std::uint64_t>(index);
    p.stamp = rep.stamp_s;
    const geometry::SE3 T_cam_obj = T_out_ref() * o.T_ref_obj;
    const Eigen::Vector3d& t = T_cam_obj.translation();
    const Eigen::Quaterniond& q = T_cam_obj.quaternion();
    p.t = {t.x(), t.y(), t.z()};
    p.q = {q.w(), q.x(), q.y(), q.z()};
    const geometry::Matrix6d cov = published_covariance(o);
    for (int rr = 0; rr < 6; ++rr)
      for (int cc = 0; cc < 6; ++cc) p.cov[static_cast<std::size_t>(rr * 6 + cc)] = cov(rr, cc);
    p.quality = std::isfinite(o.quality) ? std::clamp(o.quality, 0.0, 1.0) : 0.0;
    p.status = to_protocol(o.status);
    p.ref = opt_.reference_frame;
    ev->pose_lines.push_back(shared_line(protocol::format(p)));
    ev->poses.push_back(std::move(p));
  }
  // Objects whose cycle threw this frame leave the scene (the others went on, see VisionCycle).
  for (std::size_t i = objs.size(); i-- > 0;)
    if (i < rep.objects.size() && rep.objects[i].failed) object_failed(i, rep.objects[i].error, rep.stamp_s);
  // Failed objects are reported, with the pose they had and a covariance that keeps growing.
  for (ObjectEntry& e : objects_) {
    if (!e.failed) continue;
    ++st.failed;
    protocol::ObjectPoseEvent p;
    p.object = e.name;
    p.frame = static_cast<std::uint64_t>(index);
    p.stamp = rep.stamp_s;
    const Eigen::Vector3d& t = e.held_pose.translation();
    const Eigen::Quaterniond& q = e.held_pose.quaternion();
    p.t = {t.x(), t.y(), t.z()};
    p.q = {q.w(), q.x(), q.y(), q.z()};
    filter::PoseFilter f = e.hold;
    f.predict(std::max(0.0, rep.stamp_s - e.hold_stamp));
    const geometry::SE3 T_cam_ref = T_out_ref();
    const geometry::Matrix6d Ad = geometry::adjoint(T_cam_ref);
    const geometry::Matrix6d cov =
        geometry::translation_rotation_covariance(e.held_pose, Ad * f.pose_covariance() * Ad.transpose());
    for (int rr = 0; rr < 6; ++rr)
      for (int cc = 0; cc < 6; ++cc) p.cov[static_cast<std::size_t>(rr * 6 + cc)] = cov(rr, cc);
    p.quality = 0.0;
    p.status = protocol::TrackStatus::kFailed;
    p.ref = opt_.reference_frame;
    ev->pose_lines.push_back(shared_line(protocol::format(p)));
    ev->poses.push_back(std::move(p));
  }
  st.features_found = st.features_used + st.outliers;
  st.cameras = camera_status();
  tracked_ = tracked;
  failed_ = static_cast<int>(st.failed);
  ev->status_line = shared_line(protocol::format(st));
  if (on_frame_) on_frame_(ev);
  frames_ = index + 1;

  if (log_) {
    std::fprintf(log_, "%lld,%.6f,%.4f,%.4f,%.4f,%.4f,%d,%d,%d,%d,%llu,%llu,%llu,%d,%d,%d,%llu\n",
                 static_cast<long long>(index), rep.stamp_s, rep.cycle_ms, rep.visibility_ms, rep.track_ms,
                 rep.solve_ms, rep.degrade_level, rep.features_dropped, tracked, visible,
                 static_cast<unsigned long long>(st.features_found), static_cast<unsigned long long>(st.features_used),
                 static_cast<unsigned long long>(st.outliers), found_obs, used_obs, outlier_obs,
                 static_cast<unsigned long long>(st.overruns));
    std::fflush(log_);
  }
  if (display_ && on_overlay_) publish_overlay(rep, index);
}

void TrackingService::publish_overlay(const pipeline::CycleReport& rep, std::int64_t index) {
  // The live view is a convenience: a failure to draw it (OpenCV, memory) costs this picture only.
  try {
    auto vis = std::make_shared<cv::Mat>();
    // The first camera's view (the monitor shows one picture).
    if (frames_in_[0].channels() == 3) {
      frames_in_[0].copyTo(*vis);
    } else {
      cv::cvtColor(greys_[0], *vis, cv::COLOR_GRAY2BGR);
    }
    viz::draw_overlay(*vis, scene_, cycle_, 0, rep);
    on_overlay_(std::move(vis), index);
  } catch (const std::exception& e) {
    if (worth_logging(++faults_)) V4R_LOG_ERROR("v4r serve: frame {}: no overlay: {}", index, e.what());
  }
}

void TrackingService::object_failed(std::size_t i, const std::string& error, double stamp) {
  scene::Object& o = scene_.objects()[i];
  if (ObjectEntry* e = find(o.name)) {
    e->failed = true;
    e->error = error;
    e->held_pose = T_out_ref() * o.T_ref_obj;
    e->hold = o.filter;
    if (!e->hold.initialised()) e->hold.reset(o.T_ref_obj, o.covariance);
    e->hold_stamp = stamp;
  }
  V4R_LOG_ERROR("v4r serve: object {}: its cycle failed at {:.3f} s: {}; it is reported as failed until SetPose or "
                "AddModel, the other objects keep running",
                o.name, stamp, error);
  scene_.remove_object(i);
}

void TrackingService::count_objects() {
  tracked_ = static_cast<int>(std::count_if(scene_.objects().begin(), scene_.objects().end(), [](const scene::Object& o) {
    return o.status != scene::TrackStatus::kUninitialised;
  }));
  failed_ = static_cast<int>(std::count_if(objects_.begin(), objects_.end(), [](const ObjectEntry& e) { return e.failed; }));
}

geometry::SE3 TrackingService::T_out_ref() const {
  // Published poses: T_ref_obj with a named reference frame (--scene), else T_cam_obj of the one camera.
  return opt_.reference_frame.empty() ? scene_.cameras()[0].T_ref_cam.inverse() : geometry::SE3();
}

geometry::Matrix6d TrackingService::published_covariance(const scene::Object& o) const {
  // The cycle keeps o.covariance honest (the prediction's, growing, while lost). Published: of
  // (translation, rotation) of T_cam_obj in the camera frame, as poses.csv and ROS have it.
  const geometry::SE3 T_cam_ref = T_out_ref();
  const geometry::Matrix6d Ad = geometry::adjoint(T_cam_ref);
  return geometry::translation_rotation_covariance(T_cam_ref * o.T_ref_obj, Ad * o.covariance * Ad.transpose());
}

}  // namespace v4r::server
