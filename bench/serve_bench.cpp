// v4r - robust model-based object tracking. MIT licence.
// `v4r serve` on loopback: latency from the release of a frame to the vision cycle until its
// ObjectPose line has been received by every subscribed client, p50 / p99 / max over 120 frames
// at 60 fps, with 1 and with 100 subscribers (one reading thread each, as separate robot processes
// would). Counters: p50_ms, p99_ms, max_ms, samples.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <future>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <unistd.h>

#include "v4r/geometry/look_at.hpp"
#include "v4r/protocol/protocol.hpp"
#include "v4r/server/client.hpp"
#include "v4r/server/server.hpp"
#include "v4r/synth/renderer.hpp"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using v4r::server::Client;
using Clock = std::chrono::steady_clock;

constexpr int kRendered = 30;   // frames rendered
constexpr int kPlayed = 120;    // frames played, back and forth over the rendered ones
constexpr double kFps = 60.0;

/// The ship mockup rendered once into a temporary folder (removed at exit), with 120 frame names
/// played back and forth so that the motion stays continuous.
struct Sequence {
  fs::path dir;
  v4r::geometry::PinholeCamera camera;
  v4r::geometry::SE3 T0;
  std::string cao;
  std::string error;
  ~Sequence() {
    std::error_code ec;
    if (!dir.empty()) fs::remove_all(dir, ec);
  }
};

const Sequence& sequence() {
  static Sequence s = [] {
    Sequence q;
    q.dir = fs::temp_directory_path() / ("v4r_serve_bench_" + std::to_string(::getpid()));
    q.camera = v4r::synth::default_camera();
    q.cao = v4r::synth::ship_mockup_cao();
    v4r::synth::TrajectorySpec spec;
    spec.frames = kRendered;
    spec.T0 = v4r::geometry::look_at(0.6, -0.6, 0.75);
    const auto truth = v4r::synth::make_trajectory(spec);
    q.T0 = truth.front();
    v4r::synth::RenderOptions ro;
    ro.seed = 7;
    if (auto r = v4r::synth::write_sequence(q.dir.string(), q.cao, q.camera, truth, ro); !r) {
      q.error = r.error().to_string();
      return q;
    }
    fs::create_directories(q.dir / "played");
    const int period = 2 * (kRendered - 1);
    for (int i = 0; i < kPlayed; ++i) {
      const int k = i % period;
      const int src = k < kRendered ? k : period - k;
      std::error_code ec;
      fs::create_symlink(q.dir / "frames" / fmt::format("{:06d}.png", src), q.dir / "played" / fmt::format("{:06d}.png", i),
                         ec);
      if (ec) q.error = "cannot link frames: " + ec.message();
    }
    return q;
  }();
  return s;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

bool ok(const v4r::Expected<std::string>& r) { return r && r->starts_with("OK "); }

/// Plays the sequence once through a fresh server; returns the latencies in ms or an error text.
std::string run_once(int subscribers, std::vector<double>& ms) {
  const Sequence& seq = sequence();
  if (!seq.error.empty()) return seq.error;
  v4r::server::ServerOptions o;
  o.camera = seq.camera;
  o.input = (seq.dir / "played").string();
  o.fps = kFps;
  o.port = 0;
  o.paused = true;
  o.handle_signals = false;
  auto srv = v4r::server::Server::create(o);
  if (!srv) return srv.error().to_string();
  (*srv)->start();
  const std::uint16_t port = (*srv)->port();
  auto setup = Client::connect("127.0.0.1", port);
  if (!setup) return setup.error().to_string();
  const Eigen::Vector3d t = seq.T0.translation(), r = seq.T0.rvec();
  if (!ok(setup->request("AddObject name=ship")) ||
      !ok(setup->request_with_payload(fmt::format("AddModel object=ship format=cao bytes={}", seq.cao.size()), seq.cao)) ||
      !ok(setup->request(fmt::format("SetPose object=ship t={},{},{} r={},{},{}", t.x(), t.y(), t.z(), r.x(), r.y(), r.z()))))
    return "setting up the object failed";
  std::vector<Client> clients;
  for (int i = 0; i < subscribers; ++i) {
    auto c = Client::connect("127.0.0.1", port);
    if (!c) return c.error().to_string();
    if (!ok(c->request("Subscribe what=ObjectPose"))) return "Subscribe failed";
    clients.push_back(std::move(*c));
  }
  std::vector<std::vector<Clock::time_point>> received(subscribers, std::vector<Clock::time_point>(kPlayed));
  if (!ok(setup->request("Start"))) return "Start failed";
  std::vector<std::future<int>> readers;
  for (int i = 0; i < subscribers; ++i)
    readers.push_back(std::async(std::launch::async, [&, i] {
      int got = 0;
      while (got < kPlayed) {
        auto line = clients[i].next_event(10s);
        if (!line) break;
        const auto ev = v4r::protocol::parse_object_pose(*line);
        if (const auto* p = std::get_if<v4r::protocol::ObjectPoseEvent>(&ev); p && p->frame < kPlayed) {
          received[i][p->frame] = Clock::now();
          ++got;
        }
      }
      return got;
    }));
  int complete = 0;
  for (auto& f : readers) complete += f.get() == kPlayed ? 1 : 0;
  const auto released = (*srv)->frame_release_times();
  (*srv)->stop();
  for (int i = 0; i < subscribers; ++i)
    for (int f = 0; f < kPlayed && f < static_cast<int>(released.size()); ++f)
      if (received[i][f] != Clock::time_point{})
        ms.push_back(std::chrono::duration<double, std::milli>(received[i][f] - released[f]).count());
  if (complete != subscribers) return fmt::format("{} of {} subscribers missed frames", subscribers - complete, subscribers);
  return {};
}

void BM_ServeFrameToObjectPose(benchmark::State& st) {
  const int subscribers = static_cast<int>(st.range(0));
  std::vector<double> ms;
  for (auto _ : st) {
    if (const std::string err = run_once(subscribers, ms); !err.empty()) {
      st.SkipWithError(err.c_str());
      return;
    }
  }
  st.counters["p50_ms"] = quantile(ms, 0.5);
  st.counters["p99_ms"] = quantile(ms, 0.99);
  st.counters["max_ms"] = ms.empty() ? 0.0 : *std::max_element(ms.begin(), ms.end());
  st.counters["samples"] = static_cast<double>(ms.size());
}
BENCHMARK(BM_ServeFrameToObjectPose)->Arg(1)->Arg(100)->Iterations(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
