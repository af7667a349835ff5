// v4r - robust model-based object tracking. MIT licence.
// ROS 2 messages through Cyclone DDS's C API, with the types idlc made from
// third_party/ros2_interfaces/v4r_ros2.idl.

#include "v4r/ros2/ros2_publisher.hpp"

#include <fmt/format.h>

#include <atomic>
#include <deque>
#include <cmath>
#include <string_view>
#include <vector>

#include <dds/dds.h>

#include "v4r/core/log.hpp"
#include "v4r/server/tracking_service.hpp"
#include "v4r_ros2.h"

namespace v4r::ros2 {
namespace {

bool name_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
}

/// Seconds -> builtin_interfaces/Time (negative stamps: 0).
builtin_interfaces_msg_dds__Time_ to_time(double s) {
  builtin_interfaces_msg_dds__Time_ t{};
  if (!(s > 0.0) || !std::isfinite(s)) return t;
  const double sec = std::floor(s);
  t.sec_ = static_cast<std::int32_t>(std::min(sec, 2147483647.0));
  t.nanosec_ = static_cast<std::uint32_t>(std::min(999999999.0, std::round((s - sec) * 1e9)));
  return t;
}

/// A DDS entity deleted with its owner.
struct Entity {
  dds_entity_t e = 0;
  Entity() = default;
  explicit Entity(dds_entity_t x) : e(x) {}
  Entity(Entity&& o) noexcept : e(o.e) { o.e = 0; }
  Entity& operator=(Entity&& o) noexcept {
    std::swap(e, o.e);
    return *this;
  }
  ~Entity() {
    if (e > 0) dds_delete(e);
  }
};

/// Logs a change in the number of subscribers of a writer (the operator sees who listens, tests
/// wait for it). `arg` is the topic's name, owned by the publisher.
void on_matched(dds_entity_t, const dds_publication_matched_status_t status, void* arg) {
  V4R_LOG_INFO("v4r serve: ROS 2: {} has {} subscriber(s)", static_cast<const std::string*>(arg)->c_str(),
               status.current_count);
}

Expected<Entity> make_writer(dds_entity_t participant, const dds_topic_descriptor_t* type, const std::string& topic,
                             int depth) {
  const dds_entity_t t = dds_create_topic(participant, type, topic.c_str(), nullptr, nullptr);
  if (t < 0) return make_error(fmt::format("cannot create DDS topic {}: {}", topic, dds_strretcode(t)));
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, depth);
  dds_listener_t* listener = dds_create_listener(const_cast<std::string*>(&topic));
  dds_lset_publication_matched(listener, on_matched);
  const dds_entity_t w = dds_create_writer(participant, t, qos, listener);
  dds_delete_listener(listener);
  dds_delete_qos(qos);
  if (w < 0) return make_error(fmt::format("cannot create DDS writer on {}: {}", topic, dds_strretcode(w)));
  return Entity(w);
}

}  // namespace

Expected<void> check_namespace(const std::string& ns) {
  if (ns == "/") return {};
  bool ok = ns.size() >= 2 && ns.front() == '/' && ns.back() != '/';
  for (std::size_t i = 1; ok && i < ns.size(); ++i) {
    const char c = ns[i];
    if (c == '/') {
      ok = ns[i - 1] != '/';
    } else {
      ok = name_char(c) && !(ns[i - 1] == '/' && c >= '0' && c <= '9');
    }
  }
  if (!ok)
    return make_error("--ros2-namespace", 0, 0,
                      fmt::format("'{}' is not a ROS namespace (\"/\" or /name[/name...], names of [A-Za-z0-9_] "
                                  "not starting with a digit)",
                                  ns));
  return {};
}

std::string ros_name(const std::string& object) {
  std::string n = object.empty() ? std::string("_") : object;
  for (char& c : n)
    if (!name_char(c)) c = '_';
  if (n[0] >= '0' && n[0] <= '9') n.insert(n.begin(), '_');
  return n;
}

struct Ros2Publisher::Impl {
  Ros2Options opt;
  std::deque<std::string> topic_names;  ///< the matched-listeners' argument (stable addresses)
  Entity participant;
  Entity tf_writer;
  struct ObjectWriters {
    std::string name;    ///< v4r's object name
    std::string child;   ///< its ROS name (child frame id)
    Entity pose, status;
    std::string status_text;
  };
  std::vector<ObjectWriters> objects;  ///< reserved to max_objects: pointers stay valid
  std::vector<geometry_msgs_msg_dds__TransformStamped_> transforms;
  std::atomic<std::uint64_t> published{0}, errors{0};

  ObjectWriters* writers_for(const std::string& name) {
    for (ObjectWriters& w : objects)
      if (w.name == name) return &w;
    if (objects.size() >= opt.max_objects) return nullptr;
    const std::string child = ros_name(name);
    const std::string base = (opt.ns == "/" ? std::string("rt/") : "rt" + opt.ns + "/") + child;
    topic_names.push_back(base + "/pose");
    auto pose = make_writer(participant.e, &geometry_msgs_msg_dds__PoseWithCovarianceStamped__desc, topic_names.back(), 10);
    topic_names.push_back(base + "/status");
    auto status = make_writer(participant.e, &std_msgs_msg_dds__String__desc, topic_names.back(), 10);
    if (!pose || !status) return nullptr;
    objects.push_back(ObjectWriters{name, child, std::move(*pose), std::move(*status), std::string()});
    objects.back().status_text.reserve(16);
    return &objects.back();
  }
};

Ros2Publisher::Ros2Publisher(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Ros2Publisher::~Ros2Publisher() = default;

Expected<std::unique_ptr<Ros2Publisher>> Ros2Publisher::create(const Ros2Options& options) {
  if (options.domain < 0 || options.domain > 232)
    return make_error("--ros2-domain", 0, 0, fmt::format("domain {} is outside 0..232", options.domain));
  if (auto r = check_namespace(options.ns); !r) return r.error();
  if (options.frame_id.empty()) return make_error("--ros2-frame-id", 0, 0, "the frame id must not be empty");
  auto impl = std::make_unique<Impl>();
  impl->opt = options;
  const dds_entity_t p = dds_create_participant(static_cast<dds_domainid_t>(options.domain), nullptr, nullptr);
  if (p < 0)
    return make_error(fmt::format("cannot join DDS domain {} (check CYCLONEDDS_URI): {}", options.domain,
                                  dds_strretcode(p)));
  impl->participant = Entity(p);
  impl->topic_names.emplace_back("rt/tf");
  auto tf = make_writer(p, &tf2_msgs_msg_dds__TFMessage__desc, impl->topic_names.back(), 100);
  if (!tf) return tf.error();
  impl->tf_writer = std::move(*tf);
  impl->objects.reserve(options.max_objects);
  impl->transforms.resize(options.max_objects);
  return std::unique_ptr<Ros2Publisher>(new Ros2Publisher(std::move(impl)));
}

void Ros2Publisher::publish(const server::FrameEvents& frame) noexcept {
  Impl& d = *impl_;
  try {
    const builtin_interfaces_msg_dds__Time_ stamp = to_time(frame.stamp_s);
    char* frame_id = const_cast<char*>(d.opt.frame_id.c_str());  // DDS only reads it
    std::uint32_t n_tf = 0;
    for (const protocol::ObjectPoseEvent& p : frame.poses) {
      Impl::ObjectWriters* w = d.writers_for(p.object);
      if (!w) {
        ++d.errors;
        continue;
      }
      geometry_msgs_msg_dds__PoseWithCovarianceStamped_ msg{};
      msg.header_.stamp_ = stamp;
      msg.header_.frame_id_ = frame_id;
      msg.pose_.pose_.position_ = {p.t[0], p.t[1], p.t[2]};
      msg.pose_.pose_.orientation_ = {p.q[1], p.q[2], p.q[3], p.q[0]};  // ROS: x y z w
      // v4r: the left tangent (v, w) of T_cam_obj, translation first; ROS: x y z, then rotation
      // about x y z. The same order: copied as it is.
      for (std::size_t i = 0; i < 36; ++i) msg.pose_.covariance_[i] = p.cov[i];
      if (dds_write(w->pose.e, &msg) == DDS_RETCODE_OK) {
        ++d.published;
      } else {
        ++d.errors;
      }
      w->status_text.assign(protocol::to_string(p.status));
      std_msgs_msg_dds__String_ status{};
      status.data_ = w->status_text.data();
      if (dds_write(w->status.e, &status) != DDS_RETCODE_OK) ++d.errors;
      geometry_msgs_msg_dds__TransformStamped_& tf = d.transforms[n_tf++];
      tf.header_.stamp_ = stamp;
      tf.header_.frame_id_ = frame_id;
      tf.child_frame_id_ = w->child.data();
      tf.transform_.translation_ = {p.t[0], p.t[1], p.t[2]};
      tf.transform_.rotation_ = msg.pose_.pose_.orientation_;
    }
    if (n_tf > 0) {
      tf2_msgs_msg_dds__TFMessage_ tfm{};
      tfm.transforms_._maximum = n_tf;
      tfm.transforms_._length = n_tf;
      tfm.transforms_._buffer = d.transforms.data();
      tfm.transforms_._release = false;
      if (dds_write(d.tf_writer.e, &tfm) != DDS_RETCODE_OK) ++d.errors;
    }
  } catch (...) {  // a new object's topic (allocation) failed: counted, the tracking goes on
    ++d.errors;
  }
}

std::uint64_t Ros2Publisher::poses_published() const { return impl_->published.load(); }
std::uint64_t Ros2Publisher::errors() const { return impl_->errors.load(); }

}  // namespace v4r::ros2
