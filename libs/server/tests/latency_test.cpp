// v4r - robust model-based object tracking. MIT licence.
// Benchmark (printed by the test): latency from the frame's release to the vision cycle until
// its ObjectPose line has been received by the clients over loopback, p50 / p99, with 1 and with
// 100 subscribers.
#include <algorithm>
#include <future>
#include <thread>

#include <fmt/format.h>

#include "fixture.hpp"

namespace v4r::server::test {
namespace {

constexpr int kLoopFrames = 120;
constexpr double kFps = 60.0;

/// 120 frames played back and forth over the 30 rendered ones (symbolic links), so that the motion
/// stays continuous.
std::string ping_pong_frames(const Sequence& seq) {
  const fs::path dir = seq.dir / "pingpong";
  if (fs::exists(dir)) return dir.string();
  fs::create_directories(dir);
  for (int i = 0; i < kLoopFrames; ++i) {
    const int period = 2 * (seq.count - 1);
    const int k = i % period;
    const int src = k < seq.count ? k : period - k;
    const fs::path from = fs::path(seq.frames) / fmt::format("{:06d}.png", src);
    const fs::path to = dir / fmt::format("{:06d}.png", i);
    std::error_code ec;
    fs::create_symlink(from, to, ec);
    if (ec) fs::copy_file(from, to, ec);
  }
  return dir.string();
}

struct Latency {
  double p50_ms = 0, p99_ms = 0, max_ms = 0;
  std::size_t samples = 0;
  bool complete = true;
};

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

Latency measure(int subscribers) {
  const Sequence& seq = ship_sequence();
  ServerOptions o = test_options(seq, kFps);
  o.input = ping_pong_frames(seq);
  auto srv = start_server(o);
  if (!srv) return {};
  Client setup = connect(*srv);
  add_model_inline(setup, "ship", seq.cao);
  EXPECT_TRUE(is_ok(ask(setup, set_pose("ship", seq.truth[0]))));
  std::vector<Client> clients;
  for (int i = 0; i < subscribers; ++i) {
    clients.push_back(connect(*srv));
    EXPECT_TRUE(is_ok(ask(clients.back(), "Subscribe what=ObjectPose")));
  }
  using TimePoint = std::chrono::steady_clock::time_point;
  std::vector<std::vector<TimePoint>> received(subscribers, std::vector<TimePoint>(kLoopFrames));
  EXPECT_TRUE(is_ok(ask(setup, "Start")));
  std::vector<std::future<bool>> futs;
  for (int i = 0; i < subscribers; ++i)
    futs.push_back(std::async(std::launch::async, [&, i] {
      PoseLog log;
      return collect(clients[i], log, [](const PoseLog& l) { return has_all(l, "ship", kLoopFrames); }, 20s,
                     [&](const protocol::ObjectPoseEvent& e) {
                       if (e.frame < kLoopFrames) received[i][e.frame] = std::chrono::steady_clock::now();
                     });
    }));
  Latency lat;
  for (auto& f : futs) lat.complete = f.get() && lat.complete;
  const auto released = srv->frame_release_times();
  std::vector<double> ms;
  for (int i = 0; i < subscribers; ++i)
    for (int f = 0; f < kLoopFrames && f < static_cast<int>(released.size()); ++f)
      if (received[i][f] != TimePoint{})
        ms.push_back(std::chrono::duration<double, std::milli>(received[i][f] - released[f]).count());
  lat.samples = ms.size();
  lat.p50_ms = quantile(ms, 0.5);
  lat.p99_ms = quantile(ms, 0.99);
  lat.max_ms = ms.empty() ? 0.0 : *std::max_element(ms.begin(), ms.end());
  return lat;
}

TEST(Latency, FrameToObjectPoseOnLoopbackWithOneAndHundredSubscribers) {
  for (const int n : {1, 100}) {
    const Latency l = measure(n);
    std::printf("[ latency ] %3d subscriber(s), %d frames at %.0f fps: frame -> ObjectPose received  p50 %.2f ms  "
                "p99 %.2f ms  max %.2f ms  (%zu samples)\n",
                n, kLoopFrames, kFps, l.p50_ms, l.p99_ms, l.max_ms, l.samples);
    EXPECT_TRUE(l.complete) << n << " subscribers: a client missed frames";
    EXPECT_EQ(l.samples, static_cast<std::size_t>(n * kLoopFrames));
    // Loose bounds (a shared 2-core machine): a cycle is ~1 ms, a frame interval 16.7 ms.
    EXPECT_LT(l.p50_ms, 20.0);
    EXPECT_LT(l.p99_ms, 100.0);
  }
}

}  // namespace
}  // namespace v4r::server::test
