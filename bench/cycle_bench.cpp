// v4r - robust model-based object tracking. MIT licence.
// The whole vision cycle at 640x480, one object, one core (Google Benchmark).
#include <memory>
#include <vector>

#include <benchmark/benchmark.h>

#include "v4r/geometry/look_at.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/tracker.hpp"
#include "v4r/synth/renderer.hpp"

using namespace v4r;

namespace {

struct Sequence {
  std::shared_ptr<const model::Model> model;
  std::vector<geometry::SE3> truth;
  std::vector<cv::Mat> frames;
};

const Sequence& sequence(bool ship) {
  static Sequence seq[2];
  Sequence& s = seq[ship ? 1 : 0];
  if (s.frames.empty()) {
    auto m = model::parse_cao(ship ? synth::ship_mockup_cao() : synth::box_cao(), ship ? "ship" : "box");
    s.model = std::make_shared<const model::Model>(std::move(*m));
    synth::TrajectorySpec spec;
    spec.frames = 120;
    spec.T0 = geometry::look_at(ship ? 0.7 : 0.55, -0.6, 0.75);
    s.truth = synth::make_trajectory(spec);
    synth::RenderOptions ro;
    ro.colour = false;
    synth::Renderer r(synth::default_camera(), ro);
    for (int i = 0; i < spec.frames; ++i) s.frames.push_back(r.render(*s.model, s.truth[i], i));
  }
  return s;
}

void BM_VisionCycle(benchmark::State& state) {
  const Sequence& s = sequence(state.range(0) == 1);
  pipeline::SingleObjectTracker tracker(s.model, synth::default_camera());
  tracker.set_pose(s.truth[0]);
  std::size_t i = 0;
  double used = 0, n = 0;
  for (auto _ : state) {
    if (i == s.frames.size()) {
      state.PauseTiming();
      i = 0;
      tracker.set_pose(s.truth[0]);
      state.ResumeTiming();
    }
    const auto r = tracker.track(io::as_view(s.frames[i++]));
    used += r.report.features_used;
    n += 1;
    benchmark::DoNotOptimize(r);
  }
  state.counters["features_used"] = used / std::max(1.0, n);
}
// Per-frame median and p99 come from `v4r bench`, which times every cycle; this reports means.
BENCHMARK(BM_VisionCycle)->Arg(0)->Arg(1)->ArgName("ship")->Unit(benchmark::kMicrosecond);

}  // namespace

