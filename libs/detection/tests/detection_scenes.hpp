// v4r - robust model-based object tracking. MIT licence.
// Test scenes for the detector (shared by the unit tests and bench/detection_eval.cpp): random
// poses over a view range, rendered with the synth renderer under a named condition, and
// object-free images (clutter backgrounds, real photos).
#pragma once

#include <array>
#include <cmath>
#include <random>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "v4r/detection/detector_params.hpp"
#include "v4r/detection/template_set.hpp"
#include "v4r/geometry/look_at.hpp"
#include "v4r/synth/conditions.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::detection::scenes {

/// Scene conditions of the detection tests.
enum class Scene { kPlain, kTextured, kClutter, kNoise, kBlur, kOcclusion };
inline const char* scene_name(Scene s) {
  switch (s) {
    case Scene::kPlain: return "plain";
    case Scene::kTextured: return "textured";
    case Scene::kClutter: return "clutter";
    case Scene::kNoise: return "noise";
    case Scene::kBlur: return "blur";
    case Scene::kOcclusion: return "occlusion30";
  }
  return "?";
}

/// A random pose in the view range `v` (automatic distances resolved for `m` and `cam`; shrunk by `inset` of each span so that the truth is not on
/// the border of the sampled range) with the model's centre at a random pixel that keeps the
/// model's bounding sphere `margin_px` inside the image.
inline geometry::SE3 random_pose(const model::Model& m, const ViewRange& v, const geometry::PinholeCamera& cam,
                                 std::mt19937& rng, double inset = 0.05, double margin_px = 10.0) {
  constexpr double kDeg = 3.14159265358979323846 / 180.0;
  const auto uni = [&](double lo, double hi) {
    const double d = (hi - lo) * inset;
    return std::uniform_real_distribution<double>(lo + d, std::max(lo + d, hi - d))(rng);
  };
  const double el = uni(v.elevation_min_deg, v.elevation_max_deg) * kDeg;
  const double az = uni(v.azimuth_min_deg, v.azimuth_max_deg) * kDeg;
  const double ip = uni(v.inplane_min_deg, v.inplane_max_deg) * kDeg;
  const ModelExtent ext = model_extent(m);
  const ViewRange rv = resolve_view_range(v, ext.radius, cam.focal());
  const double dist = std::exp(uni(std::log(rv.distance_min_m), std::log(rv.distance_max_m)));
  const Eigen::Vector3d c = ext.centre;
  const double r = ext.radius;
  const geometry::SE3 T0 = geometry::SE3::from_rvec(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, ip)) *
                           geometry::look_at(dist, az, el, c);
  const double rpx = cam.focal() * r / dist + margin_px;
  const double u = std::uniform_real_distribution<double>(std::min(rpx, cam.width / 2.0), std::max(cam.width - rpx, cam.width / 2.0))(rng);
  const double w = std::uniform_real_distribution<double>(std::min(rpx, cam.height / 2.0), std::max(cam.height - rpx, cam.height / 2.0))(rng);
  const Eigen::Vector3d ray = Eigen::Vector3d((u - cam.cx) / cam.fx, (w - cam.cy) / cam.fy, 1.0).normalized();
  return geometry::SE3(Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), ray), Eigen::Vector3d::Zero()) * T0;
}

/// The motion over the exposure of a kBlur scene (4 mm and 1 degree): it starts at
/// exp(blur_motion()) * T and ends at T, so the pose in its middle is exp(blur_motion() / 2) * T.
inline geometry::Vector6d blur_motion() {
  return (geometry::Vector6d() << 0.0035, -0.002, 0.0, 0.008, 0.012, 0.006).finished();
}

/// Renders `m` at `T` under scene condition `s` (colour, 640x480 for the default camera);
/// kOcclusion covers 30 % of the object's area with the renderer's occluder.
inline cv::Mat render_scene(const model::Model& m, const geometry::SE3& T, const geometry::PinholeCamera& cam, Scene s,
                            std::uint32_t seed) {
  synth::RenderOptions ro;
  ro.seed = seed;
  ro.cycle_frames = 2;
  switch (s) {
    case Scene::kPlain: ro.textured_background = false; break;
    case Scene::kTextured: break;
    case Scene::kClutter: ro = synth::options_for(synth::Condition::kClutter, ro); break;
    case Scene::kNoise: ro = synth::options_for(synth::Condition::kNoise, ro); break;
    case Scene::kBlur: ro = synth::options_for(synth::Condition::kBlur, ro); break;
    case Scene::kOcclusion:
      ro = synth::options_for(synth::Condition::kOcclusion, ro);
      ro.occluder.peak_coverage = 0.30;
      break;
  }
  synth::Renderer r(cam, ro);
  r.set_scene_reference(m, {T, T});
  if (s == Scene::kBlur) {
    const geometry::SE3 prev = geometry::SE3::exp(blur_motion()) * T;
    return r.render(m, T, 1, &prev);
  }
  return r.render(m, T, s == Scene::kOcclusion ? 1 : 0);
}

/// An object-free image: the cluttered background of the renderer (with sensor noise) for
/// `kind` 0, else a 640x480 crop (at a random place, after a random scale 0.6..1) of a real photo
/// at `photo_path`. Empty when the photo cannot be read.
inline cv::Mat empty_scene(const geometry::PinholeCamera& cam, int kind, const std::string& photo_path, std::mt19937& rng) {
  if (kind == 0) {
    synth::RenderOptions ro = synth::options_for(synth::Condition::kClutter);
    ro.seed = static_cast<std::uint32_t>(rng());
    synth::Renderer r(cam, ro);
    cv::Mat noise(r.background().size(), CV_32FC3);
    cv::randn(noise, cv::Scalar::all(0), cv::Scalar::all(3));
    cv::Mat out;
    cv::Mat(r.background() + noise).convertTo(out, CV_8UC3);
    return out;
  }
  cv::Mat img = cv::imread(photo_path, cv::IMREAD_COLOR);
  if (img.empty()) return {};
  const double s = std::uniform_real_distribution<double>(0.6, 1.0)(rng);
  const double need = std::max(static_cast<double>(cam.width) / img.cols, static_cast<double>(cam.height) / img.rows);
  const double f = std::max(s, need);
  cv::Mat scaled;
  cv::resize(img, scaled, cv::Size(), f, f, cv::INTER_AREA);
  const int x = std::uniform_int_distribution<int>(0, scaled.cols - cam.width)(rng);
  const int y = std::uniform_int_distribution<int>(0, scaled.rows - cam.height)(rng);
  return scaled(cv::Rect(x, y, cam.width, cam.height)).clone();
}

/// The paper's green household sponge as a box (synth::sponge_cao, data/sponge.cao): every face
/// `colour=0.2,0.6,0.1`.
inline std::string sponge_cao() { return synth::sponge_cao(); }

/// Paints `n` random shaded patches (ellipses and rectangles) of colours other than green onto
/// `img` where `keep` (CV_8UC1, may be empty) is 0: coloured things on the table, behind the object.
inline void add_colour_clutter(cv::Mat& img, const cv::Mat& keep, int n, std::mt19937& rng) {
  static const std::array<cv::Scalar, 8> kPalette{
      cv::Scalar(40, 40, 200),  cv::Scalar(200, 80, 30),  cv::Scalar(40, 200, 230), cv::Scalar(30, 120, 240),
      cv::Scalar(180, 50, 180), cv::Scalar(40, 70, 120), cv::Scalar(200, 200, 60), cv::Scalar(120, 120, 120)};
  cv::Mat layer = img.clone();
  const auto uni = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  for (int i = 0; i < n; ++i) {
    const cv::Scalar base = kPalette[static_cast<std::size_t>(uni(0, static_cast<int>(kPalette.size()) - 1))];
    const double shade = std::uniform_real_distribution<double>(0.6, 1.1)(rng);
    const cv::Scalar c = base * shade;
    const cv::Point centre(uni(0, img.cols - 1), uni(0, img.rows - 1));
    const cv::Size axes(uni(15, 90), uni(10, 60));
    if (i % 2 == 0) cv::ellipse(layer, centre, axes, uni(0, 180), 0, 360, c, cv::FILLED, cv::LINE_AA);
    else cv::rectangle(layer, cv::Rect(centre - cv::Point(axes.width, axes.height), axes * 2), c, cv::FILLED, cv::LINE_AA);
  }
  if (keep.empty()) {
    layer.copyTo(img);
    return;
  }
  cv::Mat behind;
  cv::bitwise_not(keep, behind);
  layer.copyTo(img, behind);
}

/// The sponge at `T` on a cluttered table (the renderer's clutter condition) with 8 coloured
/// patches behind it; without `with_object`, the same table without it.
inline cv::Mat render_sponge_scene(const model::Model& m, const geometry::SE3& T, const geometry::PinholeCamera& cam,
                                   std::uint32_t seed, bool with_object = true) {
  synth::RenderOptions ro = synth::options_for(synth::Condition::kClutter);
  ro.seed = seed;
  ro.cycle_frames = 2;
  synth::Renderer r(cam, ro);
  r.set_scene_reference(m, {T, T});
  std::mt19937 rng(seed * 7919u + 1u);
  cv::Mat img;
  if (with_object) {
    synth::FrameInfo info;
    img = r.render(m, T, 0, nullptr, &info);
    // The patches are painted after the sensor noise: give them their own.
    add_colour_clutter(img, info.object_mask, 8, rng);
  } else {
    r.background().convertTo(img, CV_8UC3);
    add_colour_clutter(img, cv::Mat(), 8, rng);
  }
  cv::Mat noise(img.size(), CV_16SC3);
  cv::randn(noise, cv::Scalar::all(0), cv::Scalar::all(2));
  cv::Mat out;
  cv::add(img, noise, out, cv::noArray(), CV_8UC3);
  return out;
}

}  // namespace v4r::detection::scenes
