// v4r - robust model-based object tracking. MIT licence.
// The detector at 640x480 on one core (Google Benchmark): a whole detect() (gradients, search,
// refinement and verification of the hypotheses) on rendered colour images of the box in clutter,
// the template build of the box over the default view range, and the edge test of one pose.
#include <array>
#include <memory>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "../libs/detection/tests/detection_scenes.hpp"
#include "v4r/detection/detector.hpp"
#include "v4r/detection/edge_alignment.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/cao_reader.hpp"

using namespace v4r;
using namespace v4r::detection;

namespace {

struct Setup {
  std::shared_ptr<const model::Model> model;
  std::shared_ptr<const TemplateSet> templates;
  std::vector<cv::Mat> images;
  DetectorParams params;
};

const Setup& setup() {
  static Setup s;
  if (!s.images.empty()) return s;
  auto m = model::parse_cao(synth::box_cao(), "box");
  s.model = std::make_shared<const model::Model>(std::move(*m));
  const auto cam = synth::default_camera();
  s.templates = std::make_shared<const TemplateSet>(std::move(*build_templates(*s.model, cam, s.params)));
  std::mt19937 rng(7);
  for (int k = 0; k < 8; ++k) {
    const geometry::SE3 T = scenes::random_pose(*s.model, s.params.views, cam, rng);
    s.images.push_back(scenes::render_scene(*s.model, T, cam, scenes::Scene::kClutter, 50u + static_cast<unsigned>(k)));
  }
  return s;
}

void BM_DetectBoxInClutter(benchmark::State& state) {
  const Setup& s = setup();
  Detector det(s.model, s.templates, synth::default_camera(), s.params);
  std::array<Hypothesis, 16> hyp;
  std::size_t k = 0;
  for (auto _ : state) {
    const DetectionResult r = det.detect(io::as_colour_view(s.images[k++ % s.images.size()]), hyp);
    benchmark::DoNotOptimize(r.hypotheses);
  }
}
BENCHMARK(BM_DetectBoxInClutter)->Unit(benchmark::kMillisecond);

/// Issue 10 item 3: the green sponge-like box on a cluttered table with coloured things, 24 random
/// poses; Arg 1: with the colour stage (regions of the model's colour at 1/4 resolution restrict
/// the search and the gradients), Arg 0: the plain whole-image search on the same images.
struct SpongeSetup {
  std::shared_ptr<const model::Model> model;
  std::shared_ptr<const TemplateSet> templates;
  std::vector<cv::Mat> images;
  DetectorParams params;
};

const SpongeSetup& sponge_setup() {
  static SpongeSetup s;
  if (!s.images.empty()) return s;
  auto m = model::parse_cao(scenes::sponge_cao(), "sponge");
  s.model = std::make_shared<const model::Model>(std::move(*m));
  const auto cam = synth::default_camera();
  s.templates = std::make_shared<const TemplateSet>(std::move(*build_templates(*s.model, cam, s.params)));
  std::mt19937 rng(4242);
  for (int k = 0; k < 24; ++k) {
    const geometry::SE3 T = scenes::random_pose(*s.model, s.params.views, cam, rng);
    s.images.push_back(scenes::render_sponge_scene(*s.model, T, cam, 900u + static_cast<unsigned>(k)));
  }
  return s;
}

void BM_DetectSponge(benchmark::State& state) {
  const SpongeSetup& s = sponge_setup();
  DetectorParams p = s.params;
  p.colour.enabled = state.range(0) != 0;
  Detector det(s.model, s.templates, synth::default_camera(), p);
  std::array<Hypothesis, 16> hyp;
  std::size_t k = 0;
  for (auto _ : state) {
    const DetectionResult r = det.detect(io::as_colour_view(s.images[k++ % s.images.size()]), hyp);
    benchmark::DoNotOptimize(r.hypotheses);
  }
}
BENCHMARK(BM_DetectSponge)->Arg(0)->Arg(1)->ArgName("colour")->Unit(benchmark::kMillisecond);

void BM_BuildBoxTemplates(benchmark::State& state) {
  auto m = model::parse_cao(synth::box_cao(), "box");
  const DetectorParams p;
  for (auto _ : state) {
    auto ts = build_templates(*m, synth::default_camera(), p);
    benchmark::DoNotOptimize(ts->views.size());
  }
}
BENCHMARK(BM_BuildBoxTemplates)->Unit(benchmark::kMillisecond)->Iterations(1);

/// The edge test of one pose (EdgeAligner::verify) on the ship section in clutter, at the true
/// pose of 8 renders; Arg 1: with the continued-edge rule (detect.verify.continued_*), Arg 0:
/// without.
void BM_VerifySection(benchmark::State& state) {
  auto m = model::parse_cao(synth::ship_section_cao(), "section");
  DetectorParams p;
  if (state.range(0) == 0) p.verify.continued_reach = 0.0;
  const auto cam = synth::default_camera();
  EdgeAligner aligner(*m, cam, p);
  std::mt19937 rng(7);
  std::vector<GradientPyramid> g;
  std::vector<geometry::SE3> poses;
  for (int k = 0; k < 8; ++k) {
    poses.push_back(scenes::random_pose(*m, p.views, cam, rng));
    const cv::Mat img = scenes::render_scene(*m, poses.back(), cam, scenes::Scene::kClutter, 50u + static_cast<unsigned>(k));
    g.emplace_back(cam.width, cam.height, p.search.fine_spread, p.search.coarse_spread);
    g.back().compute(io::as_colour_view(img), GradientThreshold{p.verify.min_gradient, p.verify.min_gradient_floor, p.verify.noise_factor});
  }
  std::size_t k = 0;
  for (auto _ : state) {
    const Verification v = aligner.verify(g[k % g.size()], poses[k % g.size()]);
    ++k;
    benchmark::DoNotOptimize(v.in_runs);
  }
}
BENCHMARK(BM_VerifySection)->Arg(0)->Arg(1)->ArgName("continued")->Unit(benchmark::kMicrosecond);

}  // namespace
