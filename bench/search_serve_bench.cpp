// v4r - robust model-based object tracking. MIT licence.
// `v4r serve` while one object is searched (issue 10, item 5: "the tracking cycle of other
// objects keeps its budget while one is searched"): a flange tracked from its true pose and a box
// without a pose that is not in the image, so that it is searched on every frame (the worst
// case: the detector over the whole image, then its hypotheses refined). The input is played at
// 30 fps through TrackingService; per frame, the time from the frame's release to the vision
// cycle until its events are handed out (the cycle, the search's part on the tracking thread,
// the events), over 150 frames, with the search on its worker thread (search.background, the
// default) and on the tracking thread (background=false, as `v4r track`). Counters: p50_ms,
// p95_ms, max_ms of that frame time, cycle_p50_ms (VisionCycle alone), searched (frames the
// search looked at), flange_tracking (share of frames the flange was `tracking`).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <vector>

#include <unistd.h>

#include "v4r/io/loop_source.hpp"
#include "v4r/detection/template_cache.hpp"
#include "v4r/detection/template_set.hpp"
#include "v4r/geometry/look_at.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/server/tracking_service.hpp"
#include "v4r/synth/renderer.hpp"

namespace {

namespace fs = std::filesystem;
using namespace v4r;

constexpr int kFrames = 150;

using io::LoopSource;

struct Scene {
  geometry::PinholeCamera cam = synth::default_camera();
  std::shared_ptr<const model::Model> box, flange;
  geometry::SE3 T_flange;
  std::vector<cv::Mat> frames;
  detection::DetectorParams detect;  // the default view range
  fs::path cache;
  std::string error;
  ~Scene() {
    std::error_code ec;
    if (!cache.empty()) fs::remove_all(cache, ec);
  }
};

const Scene& scene() {
  static Scene s = [] {
    Scene q;
    q.box = std::make_shared<const model::Model>(std::move(*model::parse_cao(synth::box_cao(), "box")));
    q.flange = std::make_shared<const model::Model>(std::move(*model::parse_cao(synth::flange_cao(), "flange")));
    q.T_flange = geometry::look_at(0.7, 0.4, 0.8);
    synth::RenderOptions ro;
    ro.seed = 3;
    synth::Renderer r(q.cam, ro);
    for (int i = 0; i < 4; ++i) q.frames.push_back(r.render(*q.flange, q.T_flange, i));
    q.cache = fs::temp_directory_path() / ("v4r_search_serve_bench_" + std::to_string(::getpid()));
    auto t = detection::load_or_build(*q.box, q.cam, q.detect, q.cache.string());
    if (!t) q.error = t.error().to_string();
    return q;
  }();
  return s;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
}

void BM_ServeWhileSearching(benchmark::State& state) {
  const Scene& sc = scene();
  if (!sc.error.empty()) {
    state.SkipWithError(sc.error.c_str());
    return;
  }
  const bool background = state.range(0) != 0;
  std::vector<double> frame_ms, cycle_ms;
  int searching = 0, flange_tracking = 0;
  std::int64_t searched = 0;
  for (auto _ : state) {
    server::ServiceOptions o;
    o.camera = sc.cam;
    o.fps = 30.0;
    o.detect = sc.detect;
    o.cache_dir = sc.cache.string();
    o.search.background = background;
    o.objects.push_back(server::StartObject{"flange", sc.flange, sc.T_flange, true, {}});
    o.objects.push_back(server::StartObject{"box", sc.box, geometry::SE3(), false, {}});
    server::TrackingService service(std::move(o), std::make_unique<LoopSource>(sc.frames));
    std::mutex m;
    std::condition_variable cv;
    int frames = 0;
    bool ready = false;
    service.set_frame_callback([&](std::shared_ptr<const server::FrameEvents> ev) {
      const double ms = std::chrono::duration<double, std::milli>(v4r::Clock::now() - ev->released).count();
      std::scoped_lock lock(m);
      // Frames from the first one the box's templates were there (loaded from the cache).
      if (!ready && service.search() && service.search()->ready(sc.box.get())) ready = true;
      if (!ready || frames >= kFrames) return;
      bool box_searching = false, flange_ok = false;
      for (const auto& p : ev->poses) {
        if (p.object == "box") box_searching = p.status == protocol::TrackStatus::kSearching;
        if (p.object == "flange") flange_ok = p.status == protocol::TrackStatus::kTracking;
      }
      if (!box_searching) return;
      ++searching;
      flange_tracking += flange_ok ? 1 : 0;
      frame_ms.push_back(ms);
      cycle_ms.push_back(ev->status.cycle_ms);
      if (++frames == kFrames) cv.notify_all();
    });
    if (!service.open()) {
      state.SkipWithError("open failed");
      return;
    }
    service.start();
    std::unique_lock lock(m);
    if (!cv.wait_for(lock, std::chrono::seconds(300), [&] { return frames >= kFrames; })) {
      state.SkipWithError("timed out");
      return;
    }
    lock.unlock();
    searched = background && service.search()->background() ? service.search()->background()->frames_searched()
                                                            : kFrames;
    service.stop();
  }
  state.counters["p50_ms"] = percentile(frame_ms, 0.50);
  state.counters["p95_ms"] = percentile(frame_ms, 0.95);
  state.counters["max_ms"] = percentile(frame_ms, 1.0);
  state.counters["cycle_p50_ms"] = percentile(cycle_ms, 0.50);
  state.counters["searched"] = static_cast<double>(searched);
  state.counters["flange_tracking"] = searching > 0 ? static_cast<double>(flange_tracking) / searching : 0.0;
}
BENCHMARK(BM_ServeWhileSearching)->ArgName("background")->Arg(0)->Arg(1)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
