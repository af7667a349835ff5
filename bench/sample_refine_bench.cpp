// v4r - robust model-based object tracking. MIT licence.
// The per-sample measurement (pipeline::SampleRefiner) alone, one frame, one core: what it adds
// to a cycle where the line solve left an edge unused (Google Benchmark).
#include <algorithm>
#include <memory>
#include <string>

#include <benchmark/benchmark.h>
#include <opencv2/imgproc.hpp>

#include "v4r/geometry/look_at.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/sample_refinement.hpp"
#include "v4r/pipeline/view_predictor.hpp"
#include "v4r/synth/renderer.hpp"

using namespace v4r;

namespace {

/// A rendered grey frame of a built-in model and the view predicted about two pixels off it.
struct Frame {
  scene::Object obj;
  scene::Camera cam;
  scene::View view;
  cv::Mat grey;
  Frame(const std::string& cao, double distance) {
    auto m = model::parse_cao(cao, "model");
    obj.model = std::make_shared<const model::Model>(std::move(*m));
    cam.intrinsics = synth::default_camera();
    const geometry::SE3 truth = geometry::look_at(distance, -0.6, 0.75);
    synth::RenderOptions ro;
    ro.colour = false;
    cv::Mat img = synth::Renderer(cam.intrinsics, ro).render(*obj.model, truth, 0);
    if (img.channels() == 3) cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
    else grey = img;
    view.lines.resize(obj.model->lines().size());
    for (std::size_t i = 0; i < view.lines.size(); ++i) view.lines[i].edge = static_cast<model::Index>(i);
    view.face_visible.assign(obj.model->faces().size(), 0);
    geometry::Vector6d xi;
    xi << 0.003, -0.002, 0.0, 0.0, 0.0, 0.007;
    obj.T_pred = geometry::SE3::exp(xi) * truth;
    pipeline::ViewPredictor(pipeline::CycleParams{}).predict(obj, view, cam);
  }
};

void BM_SampleRefine(benchmark::State& state) {
  static const Frame frames[2] = {Frame(synth::box_cao(), 0.6), Frame(synth::ship_section_cao(), 0.6)};
  const Frame& f = frames[state.range(0)];
  pipeline::SampleRefiner refiner(pipeline::SampleRefineParams{});
  refiner.reserve();
  const image::ImageView img{f.grey.data, f.grey.cols, f.grey.rows, static_cast<int>(f.grey.step)};
  double iterations = 0, samples = 0, n = 0;
  for (auto _ : state) {
    geometry::SE3 T = f.view.T_cam_obj;
    benchmark::DoNotOptimize(refiner.refine(*f.obj.model, f.view, f.cam.intrinsics, img, 3.0, T));
    iterations += refiner.iterations();
    samples += static_cast<double>(refiner.samples());
    n += 1;
  }
  state.counters["iterations"] = iterations / std::max(1.0, n);
  state.counters["samples"] = samples / std::max(1.0, n);
}
// model 0: the box, 1: the section.
BENCHMARK(BM_SampleRefine)->Arg(0)->Arg(1)->ArgName("model")->Unit(benchmark::kMicrosecond);

}  // namespace
