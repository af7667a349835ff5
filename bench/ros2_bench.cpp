// v4r - robust model-based object tracking. MIT licence.
// ROS 2 on the wire, v4r's side of it: a 640x480 mono8 sensor_msgs/Image written to
// rt/bench_camera/image_raw (Cyclone, in this process) -> read by the `ros2:` input (newest
// first, converted to the frame handed to the tracker) -> the frame's PoseWithCovarianceStamped,
// status and /tf published by Ros2Publisher. The vision cycle itself is left out (cycle_bench
// measures it). Counters: p50_ms, p99_ms, max_ms over the iterations. Cyclone is held to loopback
// (CYCLONEDDS_URI is set to a loopback configuration unless already set). Writer and reader share
// this process, so Cyclone delivers without the network: this is v4r's own cost (take, conversion,
// serialisation of three messages); the network hops are in the wire test's cross-process,
// cross-vendor measurement (libs/ros2/wire_test).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <vector>

#include <dds/dds.h>

#include "v4r/ros2/image_source.hpp"
#include "v4r/ros2/ros2_publisher.hpp"
#include "v4r/server/tracking_service.hpp"
#include "v4r_ros2.h"

namespace {

constexpr int kDomain = 217;
constexpr const char* kLoopback =
    "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface address=\"127.0.0.1\"/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>20</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery>"
    "</Domain></CycloneDDS>";

void BM_Ros2ImageToPosePublished(benchmark::State& state) {
  setenv("CYCLONEDDS_URI", kLoopback, 0);
  auto pub = v4r::ros2::Ros2Publisher::create(v4r::ros2::Ros2Options{.domain = kDomain});
  auto src = v4r::ros2::open_image_source("ros2:/bench_camera", kDomain);
  if (!pub || !src) {
    state.SkipWithError("cannot create the DDS entities");
    return;
  }
  const dds_entity_t participant = dds_create_participant(kDomain, nullptr, nullptr);
  const dds_entity_t topic = dds_create_topic(participant, &sensor_msgs_msg_dds__Image__desc,
                                              "rt/bench_camera/image_raw", nullptr, nullptr);
  const dds_entity_t writer = dds_create_writer(participant, topic, nullptr, nullptr);
  std::vector<std::uint8_t> pixels(640 * 480, 128);
  sensor_msgs_msg_dds__Image_ img{};
  img.header_.frame_id_ = const_cast<char*>("bench_camera");
  img.height_ = 480;
  img.width_ = 640;
  img.encoding_ = const_cast<char*>("mono8");
  img.step_ = 640;
  img.data_._buffer = pixels.data();
  img.data_._length = img.data_._maximum = static_cast<std::uint32_t>(pixels.size());
  img.data_._release = false;
  // Wait until the reader matched the writer.
  for (int i = 0; i < 200; ++i) {
    dds_publication_matched_status_t st{};
    dds_get_publication_matched_status(writer, &st);
    if (st.current_count > 0) break;
    dds_sleepfor(DDS_MSECS(10));
  }
  v4r::server::FrameEvents ev;
  v4r::protocol::ObjectPoseEvent pose;
  pose.object = "bench";
  pose.t = {0.0, 0.0, 0.6};
  for (int i = 0; i < 6; ++i) pose.cov[static_cast<std::size_t>(i * 7)] = 1e-6;
  pose.status = v4r::protocol::TrackStatus::kTracking;
  ev.poses.push_back(pose);
  cv::Mat frame;
  std::vector<double> ms;
  ms.reserve(100000);
  std::int32_t sec = 0;
  for (auto _ : state) {
    img.header_.stamp_.sec_ = ++sec;
    const auto t0 = std::chrono::steady_clock::now();
    dds_write(writer, &img);
    auto more = (*src)->next(frame);
    if (!more || !*more) {
      state.SkipWithError("no image");
      break;
    }
    ev.stamp_s = (*src)->stamp_s();
    (*pub)->publish(ev);
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  dds_delete(participant);
  if (ms.empty()) return;
  std::sort(ms.begin(), ms.end());
  const auto at = [&](double q) { return ms[std::min(ms.size() - 1, static_cast<std::size_t>(q * (ms.size() - 1)))]; };
  state.counters["p50_ms"] = at(0.5);
  state.counters["p99_ms"] = at(0.99);
  state.counters["max_ms"] = ms.back();
}
BENCHMARK(BM_Ros2ImageToPosePublished)->Unit(benchmark::kMillisecond)->Iterations(500);

}  // namespace
