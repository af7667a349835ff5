// v4r - robust model-based object tracking. MIT licence.
// ROS 2 images and camera_info read through Cyclone DDS (types: third_party/ros2_interfaces).

#include "v4r/ros2/image_source.hpp"

#include <fmt/format.h>

#include <cmath>
#include <string_view>

#include <dds/dds.h>
#include <opencv2/imgproc.hpp>

#include "v4r/ros2/ros2_publisher.hpp"
#include "v4r_ros2.h"

namespace v4r::ros2 {
namespace {

constexpr std::string_view kScheme = "ros2:";

/// The DDS topic prefix of `ros2:/camera` ("rt/camera"), or an error naming the input.
Expected<std::string> topic_prefix(const std::string& input) {
  const std::string ns = input.substr(std::min(input.size(), kScheme.size()));
  if (ns == "/" || !check_namespace(ns))
    return make_error(input, 0, 0, "expected ros2:/<camera namespace>, e.g. ros2:/camera");
  return "rt" + ns;
}

/// Owns a participant (and so every entity made in it).
struct Participant {
  dds_entity_t e = 0;
  ~Participant() {
    if (e > 0) dds_delete(e);
  }
};

Expected<dds_entity_t> make_reader(dds_entity_t participant, const dds_topic_descriptor_t* type,
                                   const std::string& topic) {
  const dds_entity_t t = dds_create_topic(participant, type, topic.c_str(), nullptr, nullptr);
  if (t < 0) return make_error(fmt::format("cannot create DDS topic {}: {}", topic, dds_strretcode(t)));
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t r = dds_create_reader(participant, t, qos, nullptr);
  dds_delete_qos(qos);
  if (r < 0) return make_error(fmt::format("cannot create DDS reader on {}: {}", topic, dds_strretcode(r)));
  return r;
}

Expected<dds_entity_t> join(int domain) {
  const dds_entity_t p = dds_create_participant(static_cast<dds_domainid_t>(domain), nullptr, nullptr);
  if (p < 0)
    return make_error(fmt::format("cannot join DDS domain {} (check CYCLONEDDS_URI): {}", domain, dds_strretcode(p)));
  return p;
}

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

/// \brief The newest ROS 2 image of a topic (see open_image_source).
class ImageSource final : public io::FrameSource {
 public:
  ImageSource(dds_entity_t participant, dds_entity_t reader, std::string input, std::string topic)
      : input_(std::move(input)), topic_(std::move(topic)), reader_(reader) {
    participant_.e = participant;
    waitset_ = dds_create_waitset(participant);
    const dds_entity_t cond = dds_create_readcondition(reader_, DDS_ANY_STATE);
    dds_waitset_attach(waitset_, cond, 0);
  }

  Expected<bool> next(cv::Mat& bgr) override {
    for (;;) {
      void* samples[1] = {nullptr};
      dds_sample_info_t info[1];
      const dds_return_t n = dds_take(reader_, samples, info, 1, 1);
      if (n < 0) return make_error(input_, 0, 0, fmt::format("DDS take failed: {}", dds_strretcode(n)));
      if (n == 1) {
        Expected<bool> r = true;
        if (info[0].valid_data) r = convert(*static_cast<const sensor_msgs_msg_dds__Image_*>(samples[0]), bgr);
        const bool valid = info[0].valid_data;
        dds_return_loan(reader_, samples, n);
        if (!r || valid) return r;
        continue;
      }
      const dds_return_t w = dds_waitset_wait(waitset_, nullptr, 0, DDS_SECS(kImageTimeout.count()));
      if (w < 0) return make_error(input_, 0, 0, fmt::format("DDS wait failed: {}", dds_strretcode(w)));
      if (w == 0) {
        if (index_ > 0) return false;  // the publisher stopped: the end of this input
        return make_error(input_, 0, 0,
                          fmt::format("no image on {} within {} s", topic_, kImageTimeout.count()));
      }
    }
  }
  [[nodiscard]] std::string current_name() const override { return fmt::format("{}#{}", input_, index_ - 1); }
  [[nodiscard]] int size_hint() const override { return -1; }
  [[nodiscard]] bool live() const override { return true; }
  [[nodiscard]] double capture_time_s() const override { return received_s_; }
  [[nodiscard]] double stamp_s() const override { return stamp_s_; }

 private:
  Expected<bool> convert(const sensor_msgs_msg_dds__Image_& m, cv::Mat& bgr) {
    const std::string_view enc = m.encoding_ ? m.encoding_ : "";
    const int channels = enc == "mono8" ? 1 : (enc == "bgr8" || enc == "rgb8") ? 3 : 0;
    if (channels == 0)
      return make_error(input_, 0, 0, fmt::format("image encoding '{}' is not supported (mono8, bgr8, rgb8)", enc));
    const std::uint64_t need = static_cast<std::uint64_t>(m.step_) * m.height_;
    if (m.width_ == 0 || m.height_ == 0 || m.step_ < m.width_ * static_cast<std::uint32_t>(channels) ||
        m.data_._length < need || m.width_ > 100000 || m.height_ > 100000)
      return make_error(input_, 0, 0,
                        fmt::format("malformed image {}x{} step {} with {} bytes", m.width_, m.height_, m.step_,
                                    m.data_._length));
    const cv::Mat in(static_cast<int>(m.height_), static_cast<int>(m.width_), channels == 1 ? CV_8UC1 : CV_8UC3,
                     m.data_._buffer, m.step_);
    if (enc == "rgb8") {
      cv::cvtColor(in, bgr, cv::COLOR_RGB2BGR);
    } else {
      in.copyTo(bgr);  // reuses bgr's buffer when the size is unchanged
    }
    stamp_s_ = m.header_.stamp_.sec_ + m.header_.stamp_.nanosec_ * 1e-9;
    received_s_ = steady_seconds();
    ++index_;
    return true;
  }

  std::string input_, topic_;
  Participant participant_;
  dds_entity_t reader_ = 0, waitset_ = 0;
  std::int64_t index_ = 0;
  double stamp_s_ = -1.0, received_s_ = -1.0;
};

}  // namespace

Expected<std::unique_ptr<io::FrameSource>> open_image_source(const std::string& input, int domain) {
  auto prefix = topic_prefix(input);
  if (!prefix) return prefix.error();
  auto p = join(domain);
  if (!p) return p.error();
  Participant owner{*p};
  auto r = make_reader(*p, &sensor_msgs_msg_dds__Image__desc, *prefix + "/image_raw");
  if (!r) return r.error();
  owner.e = 0;  // handed to the source
  return std::unique_ptr<io::FrameSource>(
      std::make_unique<ImageSource>(*p, *r, input, input.substr(kScheme.size()) + "/image_raw"));
}

void register_image_input(int domain) {
  io::FrameSource::register_scheme(std::string(kScheme),
                                   [domain](const std::string& input) { return open_image_source(input, domain); });
}

Expected<geometry::PinholeCamera> wait_camera_info(const std::string& input, int domain,
                                                   std::chrono::milliseconds timeout) {
  auto prefix = topic_prefix(input);
  if (!prefix) return prefix.error();
  auto p = join(domain);
  if (!p) return p.error();
  Participant owner{*p};
  auto r = make_reader(*p, &sensor_msgs_msg_dds__CameraInfo__desc, *prefix + "/camera_info");
  if (!r) return r.error();
  const dds_entity_t ws = dds_create_waitset(*p);
  dds_waitset_attach(ws, dds_create_readcondition(*r, DDS_ANY_STATE), 0);
  const auto end = std::chrono::steady_clock::now() + timeout;
  const std::string topic = input.substr(kScheme.size()) + "/camera_info";
  for (;;) {
    void* samples[1] = {nullptr};
    dds_sample_info_t info[1];
    const dds_return_t n = dds_take(*r, samples, info, 1, 1);
    if (n == 1 && info[0].valid_data) {
      const auto& m = *static_cast<const sensor_msgs_msg_dds__CameraInfo_*>(samples[0]);
      geometry::PinholeCamera cam;
      cam.width = static_cast<int>(m.width_);
      cam.height = static_cast<int>(m.height_);
      cam.fx = m.k_[0];
      cam.fy = m.k_[4];
      cam.cx = m.k_[2];
      cam.cy = m.k_[5];
      const std::string_view model = m.distortion_model_ ? m.distortion_model_ : "";
      const bool plumb_bob = model == "plumb_bob" || model == "rational_polynomial";
      for (std::uint32_t i = 0; plumb_bob && i < 5 && i < m.d_._length; ++i) cam.dist[i] = m.d_._buffer[i];
      const bool distorted = m.d_._length > 0 && !plumb_bob;
      dds_return_loan(*r, samples, n);
      if (distorted)
        return make_error(input, 0, 0, fmt::format("{}: distortion model '{}' is not supported (plumb_bob)", topic, model));
      if (cam.width <= 0 || cam.height <= 0 || !(cam.fx > 0.0) || !(cam.fy > 0.0))
        return make_error(input, 0, 0, fmt::format("{}: invalid calibration ({}x{}, fx {}, fy {})", topic, cam.width,
                                                   cam.height, cam.fx, cam.fy));
      return cam;
    }
    if (n > 0) dds_return_loan(*r, samples, n);
    const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(end - std::chrono::steady_clock::now());
    if (left.count() <= 0)
      return make_error(input, 0, 0, fmt::format("no camera_info on {} within {} ms", topic, timeout.count()));
    dds_waitset_wait(ws, nullptr, 0, left.count());
  }
}

}  // namespace v4r::ros2
