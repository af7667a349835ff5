// v4r - robust model-based object tracking. MIT licence.
// The test renderer's cost per 640x480 frame (Google Benchmark): the flange, whose cylinder is
// ray-cast (was a timed unit test; timings belong in benchmarks).
#include <vector>

#include <benchmark/benchmark.h>

#include "v4r/geometry/look_at.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/synth/renderer.hpp"

using namespace v4r;

namespace {

void BM_RenderFlange(benchmark::State& state) {
  const synth::Renderer r(synth::default_camera());
  auto m = model::parse_cao(synth::flange_cao(), "flange.cao");
  if (!m) {
    state.SkipWithError("flange model");
    return;
  }
  synth::TrajectorySpec spec;
  spec.T0 = geometry::look_at(0.6, -0.6, 0.75);
  spec.frames = 20;
  const std::vector<geometry::SE3> traj = synth::make_trajectory(spec);
  int i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(r.render(*m, traj[static_cast<std::size_t>(i % spec.frames)], i));
    ++i;
  }
}
BENCHMARK(BM_RenderFlange)->Unit(benchmark::kMillisecond);

}  // namespace
