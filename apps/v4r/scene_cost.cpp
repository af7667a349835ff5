// v4r - robust model-based object tracking. MIT licence.
// `v4r bench --cameras N --objects M`: what extra cameras and objects cost per frame (issue 11).
#include "scene_cost.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <fmt/format.h>

#include "v4r/io/frame_source.hpp"
#include "v4r/pipeline/evaluation.hpp"
#include "v4r/pipeline/vision_cycle.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::app {

namespace {

/// Camera k of the rig in the reference frame (camera 0's): k = 1 the stereo partner
/// (12 cm to the right, toed in 5 degrees), k = 2 its mirror on the left, k = 3 24 cm right, 10 degrees.
geometry::SE3 rig_camera(int k) {
  constexpr double kDeg = M_PI / 180.0;
  const double x[] = {0.0, 0.12, -0.12, 0.24};
  const double toe[] = {0.0, -5.0, 5.0, -10.0};
  return geometry::SE3(Eigen::Quaterniond(Eigen::AngleAxisd(toe[k] * kDeg, Eigen::Vector3d::UnitY())),
                       Eigen::Vector3d(x[k], 0.0, 0.0));
}

/// Offsets (reference frame) of the object copies: one, a row of two, a 2x2 grid, spaced by
/// `d` (the model's bounding diameter) and pushed back by `back` so that they stay in view.
std::vector<Eigen::Vector3d> object_offsets(int n, double d, double back) {
  std::vector<Eigen::Vector3d> o;
  if (n == 1) return {Eigen::Vector3d::Zero()};
  if (n == 2) return {{-0.5 * d, 0.0, back}, {0.5 * d, 0.0, back}};
  const Eigen::Vector3d g[] = {{-0.5 * d, -0.5 * d, back}, {0.5 * d, -0.5 * d, back}, {-0.5 * d, 0.5 * d, back},
                               {0.5 * d, 0.5 * d, back}};
  return std::vector<Eigen::Vector3d>(g, g + n);
}

double model_diameter(const model::Model& m) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e30), hi = Eigen::Vector3d::Constant(-1e30);
  for (const auto& j : m.junctions()) {
    lo = lo.cwiseMin(j.p);
    hi = hi.cwiseMax(j.p);
  }
  for (const auto& a : m.arcs()) {
    lo = lo.cwiseMin(a.center - Eigen::Vector3d::Constant(a.radius));
    hi = hi.cwiseMax(a.center + Eigen::Vector3d::Constant(a.radius));
  }
  return (hi - lo).allFinite() && hi.x() >= lo.x() ? (hi - lo).norm() : 0.1;
}

struct RunResult {
  double median_ms = 0.0;
  pipeline::AccuracyStats object0;
};

/// The cycle over the cameras `cams` and objects `objs` (indices into the rig and the copies).
RunResult run(const SceneCostInput& in, const std::vector<int>& cams, const std::vector<int>& objs,
              const std::vector<std::vector<cv::Mat>>& frames, const std::vector<std::vector<geometry::SE3>>& T_ref_obj,
              int threads = 1) {
  std::vector<double> ms;
  std::vector<geometry::SE3> est;
  for (int r = 0; r < in.repeat; ++r) {
    pipeline::CycleParams params = in.params;
    params.budget.cycle_ms = in.budget_ms;
    params.threads = threads;
    pipeline::VisionCycle cycle(params);
    scene::Scene sc;
    for (const int c : cams) sc.add_camera(scene::Camera{fmt::format("cam{}", c), in.camera, rig_camera(c)});
    for (std::size_t k = 0; k < objs.size(); ++k) {
      (void)sc.add_object(fmt::format("object{}", objs[k]), in.model);
      sc.set_pose(k, T_ref_obj[static_cast<std::size_t>(objs[k])][0]);
    }
    std::vector<pipeline::CameraImage> images(cams.size());
    const std::size_t n = frames[0].size();
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t k = 0; k < cams.size(); ++k)
        images[k] = pipeline::CameraImage{io::as_view(frames[static_cast<std::size_t>(cams[k])][i]), {}};
      const pipeline::CycleReport& rep = cycle.process(sc, images, static_cast<double>(i) * params.frame_interval_s);
      ms.push_back(rep.cycle_ms);
      if (r == in.repeat - 1) est.push_back(sc.objects()[0].T_ref_obj);
    }
  }
  RunResult out;
  out.median_ms = pipeline::percentiles(ms).median;
  out.object0 = pipeline::evaluate(est, T_ref_obj[static_cast<std::size_t>(objs[0])]);
  return out;
}

}  // namespace

int run_scene_cost(const SceneCostInput& in) {
  const int n_cam = std::clamp(in.cameras, 1, 4), n_obj = std::clamp(in.objects, 1, 4);
  const double d = 1.1 * model_diameter(*in.model);
  const double back = n_obj > 1 ? 0.75 * d : 0.0;  // the copies side by side stay in view
  const auto offsets = object_offsets(n_obj, d, back);
  std::vector<std::vector<geometry::SE3>> T_ref_obj(static_cast<std::size_t>(n_obj));
  for (int o = 0; o < n_obj; ++o)
    for (const geometry::SE3& T : in.trajectory)
      T_ref_obj[static_cast<std::size_t>(o)].push_back(
          geometry::SE3(T.quaternion(), T.translation() + offsets[static_cast<std::size_t>(o)]));
  // Every camera's frames: each copy rendered alone, laid over the others from far to near.
  std::vector<std::vector<cv::Mat>> frames(static_cast<std::size_t>(n_cam));
  for (int c = 0; c < n_cam; ++c) {
    synth::Renderer renderer(in.camera, in.render);
    const geometry::SE3 T_cam_ref = rig_camera(c).inverse();
    for (std::size_t i = 0; i < in.trajectory.size(); ++i) {
      std::vector<int> order(static_cast<std::size_t>(n_obj));
      std::iota(order.begin(), order.end(), 0);
      std::sort(order.begin(), order.end(), [&](int a, int b) {
        return (T_cam_ref * T_ref_obj[static_cast<std::size_t>(a)][i]).translation().z() >
               (T_cam_ref * T_ref_obj[static_cast<std::size_t>(b)][i]).translation().z();
      });
      cv::Mat img;
      for (const int o : order) {
        const auto& tr = T_ref_obj[static_cast<std::size_t>(o)];
        const geometry::SE3 T = T_cam_ref * tr[i];
        const geometry::SE3 T_prev = i > 0 ? T_cam_ref * tr[i - 1] : T;
        synth::FrameInfo info;
        const cv::Mat one = renderer.render(*in.model, T, static_cast<int>(i), i > 0 ? &T_prev : nullptr, &info);
        if (img.empty()) {
          img = one;
        } else {
          one.copyTo(img, info.object_mask);
        }
      }
      frames[static_cast<std::size_t>(c)].push_back(img);
    }
  }
  std::vector<int> cams(static_cast<std::size_t>(n_cam)), objs(static_cast<std::size_t>(n_obj));
  std::iota(cams.begin(), cams.end(), 0);
  std::iota(objs.begin(), objs.end(), 0);
  const RunResult all = run(in, cams, objs, frames, T_ref_obj);
  // One camera and one object: each camera alone (with object 0) and each object alone (in
  // camera 0), averaged: "one" is a typical single camera or object of this arrangement.
  fmt::print("v4r bench: {} camera(s) x {} object(s), {} frames x {} runs (one thread first)\n", n_cam, n_obj,
             in.trajectory.size(), in.repeat);
  double one_ms = 0.0;
  int ones = 0;
  RunResult first;
  for (const int c : cams)
    for (const int o : objs) {
      if ((n_cam > 1 && o != 0) || (n_cam == 1 && c != 0)) continue;
      const RunResult one = run(in, {c}, {o}, frames, T_ref_obj);
      if (ones == 0) first = one;
      one_ms += one.median_ms;
      ++ones;
      fmt::print("  camera {} object {} alone: {:.3f} ms, object mean {:.2f} mm, {}/{} frames within 5 cm / 5 deg\n", c, o,
                 one.median_ms, one.object0.mean_translation_m * 1e3, one.object0.successes, one.object0.frames);
    }
  one_ms /= std::max(1, ones);
  fmt::print("cycle (median): {:.3f} ms for all; {:.3f} ms for one {} alone (mean of the above): {:.2f}x\n", all.median_ms,
             one_ms, n_cam > 1 ? "camera" : "object", one_ms > 0.0 ? all.median_ms / one_ms : 0.0);
  fmt::print("object 0 with all: mean {:.2f} mm {:.2f} deg, {}/{} frames within 5 cm / 5 deg (camera 0 alone: {:.2f} mm)\n",
             all.object0.mean_translation_m * 1e3, all.object0.mean_rotation_deg, all.object0.successes,
             all.object0.frames, first.object0.mean_translation_m * 1e3);
  if (in.threads > 1) {
    // What more cores buy: the same cycle over all cameras and objects on cycle.threads threads.
    const RunResult par = run(in, cams, objs, frames, T_ref_obj, in.threads);
    fmt::print("cycle (median) on {} threads: {:.3f} ms for all ({:.2f}x the one-thread cycle); object 0 mean {:.2f} mm "
               "({} as on one thread)\n",
               in.threads, par.median_ms, all.median_ms > 0.0 ? par.median_ms / all.median_ms : 0.0,
               par.object0.mean_translation_m * 1e3,
               par.object0.mean_translation_m == all.object0.mean_translation_m ? "the same" : "NOT the same");
  }
  return 0;
}

}  // namespace v4r::app
