// v4r - robust model-based object tracking. MIT licence.
// The named rendering conditions: each one changes the image the way it claims.
#include "v4r/synth/conditions.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "v4r/model/cao_reader.hpp"

namespace v4r::synth {
namespace {

using geometry::PinholeCamera;
using geometry::SE3;

constexpr int kFrames = 120;

model::Model flange() {
  auto m = model::parse_cao(flange_cao(), "flange.cao");
  if (!m) ADD_FAILURE() << m.error().to_string();
  return std::move(m).value();
}

std::vector<SE3> flange_trajectory(Condition c = Condition::kRegular) {
  TrajectorySpec spec;
  spec.frames = kFrames;
  spec.T0 = geometry::look_at(0.6, -0.6, 0.75);
  return make_trajectory(trajectory_spec_for(c, spec));
}

/// Grey, noise-free options with a fixed cycle of kFrames, then condition c.
RenderOptions quiet(Condition c) {
  RenderOptions base;
  base.colour = false;
  base.noise_sigma = 0.0;
  base.cycle_frames = kFrames;
  return options_for(c, base);
}

/// A renderer for condition-specific options, laid out for the flange trajectory.
Renderer renderer_for(const RenderOptions& o, const model::Model& m, const std::vector<SE3>& traj) {
  Renderer r(default_camera(), o);
  r.set_scene_reference(m, traj);
  return r;
}

cv::Mat render(const Renderer& r, const model::Model& m, const std::vector<SE3>& traj, int f,
               FrameInfo* info = nullptr) {
  const std::size_t i = static_cast<std::size_t>(f);
  return r.render(m, traj[i], f, f > 0 ? &traj[i - 1] : nullptr, info);
}

/// Distance (pixels) of every pixel to the nearest object pixel of `mask`.
cv::Mat distance_to(const cv::Mat& mask) {
  cv::Mat inverse, dist;
  cv::compare(mask, 0, inverse, cv::CMP_EQ);
  cv::distanceTransform(inverse, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  return dist;
}

double fraction(const cv::Mat& part, const cv::Mat& whole) {
  return static_cast<double>(cv::countNonZero(part & whole)) / std::max(1, cv::countNonZero(whole));
}

TEST(Conditions, NamesParseAndRoundTrip) {
  const std::vector<std::string> expected{"regular",   "light",    "shadow", "noise", "clutter",
                                          "occlusion", "specular", "blur",   "fast"};
  EXPECT_EQ(condition_names(), expected);
  ASSERT_EQ(all_conditions().size(), expected.size());
  for (const Condition c : all_conditions()) {
    auto p = parse_condition(condition_name(c));
    ASSERT_TRUE(p.has_value());
    EXPECT_EQ(*p, c);
  }
  auto bad = parse_condition("Shadow");
  ASSERT_FALSE(bad.has_value());
  EXPECT_NE(bad.error().to_string().find("regular, light, shadow"), std::string::npos) << bad.error().to_string();
  EXPECT_EQ(bad.error().field, "condition");
}

TEST(Conditions, RegularIsTheDefault) {
  const model::Model m = flange();
  const auto traj = flange_trajectory();
  const Renderer a(default_camera()), b(default_camera(), options_for(Condition::kRegular));
  for (const int f : {0, 7}) EXPECT_EQ(cv::norm(render(a, m, traj, f), render(b, m, traj, f), cv::NORM_INF), 0.0);
  TrajectorySpec spec;
  spec.speed = 1.5;
  for (const Condition c : all_conditions())
    if (c != Condition::kFast) {
      EXPECT_EQ(trajectory_spec_for(c, spec).speed, 1.5);
    }
}

TEST(Conditions, LightChangesTheGlobalBrightnessSmoothlyAndTurnsTheLight) {
  const model::Model m = flange();
  const auto traj = flange_trajectory();
  const Renderer reg(default_camera(), quiet(Condition::kRegular)), lit(default_camera(), quiet(Condition::kLight));
  auto ratios = [&](int f, cv::Mat& obj_ratio) {
    FrameInfo info;
    cv::Mat a, b;
    render(reg, m, traj, f).convertTo(a, CV_64F);
    render(lit, m, traj, f, &info).convertTo(b, CV_64F);
    const cv::Mat far_bg = distance_to(info.object_mask) > 10.0;
    cv::Mat inner;
    cv::erode(info.object_mask, inner, cv::Mat::ones(7, 7, CV_8U));
    cv::divide(b, cv::max(a, 1.0), obj_ratio);
    obj_ratio.setTo(0.0, inner == 0);
    return cv::mean(b, far_bg)[0] / cv::mean(a, far_bg)[0];
  };
  cv::Mat r30, r60, r90;
  EXPECT_NEAR(ratios(30, r30), 1.4, 0.02);  // brightest (a quarter cycle)
  EXPECT_NEAR(ratios(90, r90), 0.5, 0.02);  // darkest (three quarters)
  const double mid = ratios(60, r60);       // middle: gain 0.95, light turned by 100 degrees
  EXPECT_NEAR(mid, 0.95, 0.02);
  // The object's faces are lit differently (not just scaled by the gain).
  std::vector<double> v;
  for (int y = 0; y < r60.rows; ++y)
    for (int x = 0; x < r60.cols; ++x)
      if (r60.at<double>(y, x) > 0.0) v.push_back(r60.at<double>(y, x));
  ASSERT_GT(v.size(), 5000u);
  std::sort(v.begin(), v.end());
  EXPECT_GT(v[v.size() * 95 / 100] - v[v.size() * 5 / 100], 0.3);
  // Smooth: consecutive frames differ by a few percent in overall brightness at most.
  double prev = -1.0;
  for (int f = 40; f <= 46; ++f) {
    const double mean = cv::mean(render(lit, m, traj, f))[0];
    if (prev > 0) {
      EXPECT_LT(std::abs(mean / prev - 1.0), 0.04) << "frame " << f;
    }
    prev = mean;
  }
}

TEST(Conditions, ShadowBandDarkensObjectAndBackgroundWithASoftEdge) {
  const model::Model m = flange();
  const auto traj = flange_trajectory();
  const Renderer reg(default_camera(), quiet(Condition::kRegular)), sh(default_camera(), quiet(Condition::kShadow));
  int best_frame = -1, best_count = -1;
  cv::Mat best_ratio, best_mask;
  for (int f = 0; f < kFrames; f += 10) {
    FrameInfo info;
    cv::Mat a, b, ratio;
    render(reg, m, traj, f).convertTo(a, CV_64F);
    render(sh, m, traj, f, &info).convertTo(b, CV_64F);
    cv::divide(b, cv::max(a, 1.0), ratio);
    if (f == 0) {
      double lo = 0.0;
      cv::minMaxLoc(ratio, &lo);
      EXPECT_GT(lo, 0.99) << "the band starts outside the image";
    }
    const int on_object = cv::countNonZero((ratio < 0.7) & info.object_mask);
    if (on_object > best_count) {
      best_count = on_object;
      best_frame = f;
      best_ratio = ratio;
      best_mask = info.object_mask;
    }
  }
  ASSERT_GT(best_count, 2000) << "the band crosses the object";
  const cv::Mat core = best_ratio < 0.7;
  EXPECT_GT(cv::countNonZero(core & (best_mask == 0)), 5000) << "and the background";
  std::vector<double> v;
  for (int y = 0; y < core.rows; ++y)
    for (int x = 0; x < core.cols; ++x)
      if (core.at<std::uint8_t>(y, x)) v.push_back(best_ratio.at<double>(y, x));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  EXPECT_GE(v[v.size() / 2], 0.4);
  EXPECT_LE(v[v.size() / 2], 0.6);
  // Soft edge: along an object-free row the light falls from 95 % to 55 % over a few pixels.
  int rows = 0;
  for (int y = 5; y < best_ratio.rows - 5; y += 20) {
    if (cv::countNonZero(best_mask.row(y)) > 0) continue;
    const double* r = best_ratio.ptr<double>(y);
    for (int x = 1; x + 1 < best_ratio.cols; ++x) {
      if (!(r[x - 1] >= 0.95 && r[x] < 0.95)) continue;  // entering the band from the left
      double x95 = x - 1 + (r[x - 1] - 0.95) / (r[x - 1] - r[x]), x55 = -1.0;
      for (int k = x; k + 1 < best_ratio.cols && k < x + 30; ++k)
        if (r[k] >= 0.55 && r[k + 1] < 0.55) {
          x55 = k + (r[k] - 0.55) / (r[k] - r[k + 1]);
          break;
        }
      if (x55 < 0) break;
      EXPECT_GT(x55 - x95, 4.0) << "row " << y;
      EXPECT_LT(x55 - x95, 12.0) << "row " << y;
      ++rows;
      break;
    }
  }
  EXPECT_GT(rows, 3);
  ::testing::Test::RecordProperty("shadow_frame", std::to_string(best_frame));
}

TEST(Conditions, NoiseHasSigma8AndImpulses) {
  const model::Model m = flange();
  const auto traj = flange_trajectory();
  RenderOptions o = options_for(Condition::kNoise);
  o.colour = false;
  const Renderer r(default_camera(), o);
  FrameInfo info;
  const cv::Mat a = r.render(m, traj[0], 1, nullptr, &info), b = r.render(m, traj[0], 2);
  const cv::Mat bg = distance_to(info.object_mask) > 3.0;
  double sum = 0, sum2 = 0;
  long n = 0, impulses = 0, pixels = 0;
  for (int y = 0; y < a.rows; ++y)
    for (int x = 0; x < a.cols; ++x) {
      if (!bg.at<std::uint8_t>(y, x)) continue;
      const int va = a.at<std::uint8_t>(y, x), vb = b.at<std::uint8_t>(y, x);
      ++pixels;
      if (va == 0 || va == 255) ++impulses;
      if (va == 0 || va == 255 || vb == 0 || vb == 255) continue;
      const double d = va - vb;
      sum += d;
      sum2 += d * d;
      ++n;
    }
  const double sd = std::sqrt(sum2 / n - (sum / n) * (sum / n)) / std::sqrt(2.0);
  EXPECT_NEAR(sd, 8.0, 0.3);
  EXPECT_NEAR(static_cast<double>(impulses) / pixels, 0.002, 0.0004);
  ::testing::Test::RecordProperty("noise_sigma_measured", std::to_string(sd));
}

TEST(Conditions, ClutterAddsStrongStaticEdgesIncludingParallelsNearTheObject) {
  const model::Model m = flange();
  const auto traj = flange_trajectory();
  const Renderer reg = renderer_for(quiet(Condition::kRegular), m, traj);
  const Renderer clu = renderer_for(quiet(Condition::kClutter), m, traj);
  FrameInfo info;
  const cv::Mat plain = render(reg, m, traj, 0), busy = render(clu, m, traj, 0, &info);
  const cv::Mat dist = distance_to(info.object_mask);
  auto gradient = [](const cv::Mat& img, cv::Mat& gx, cv::Mat& gy) {
    cv::Sobel(img, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
    cv::Sobel(img, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
    cv::Mat mag;
    cv::magnitude(gx, gy, mag);
    return mag;
  };
  cv::Mat gx, gy, px, py, dx, dy;
  const cv::Mat strong_busy = gradient(busy, gx, gy) > 20.0, strong_plain = gradient(plain, px, py) > 20.0;
  const cv::Mat off = dist > 6.0;
  EXPECT_GT(cv::countNonZero(strong_busy & off), 5000);
  EXPECT_LT(cv::countNonZero(strong_plain & off), 50);
  // 15..45 px from the object: strong edges, mostly parallel to the nearest silhouette edge
  // (their gradient is along the direction to the object).
  const cv::Mat band = (dist >= 15.0) & (dist <= 45.0);
  (void)gradient(dist, dx, dy);
  int strong = 0, parallel = 0;
  for (int y = 0; y < band.rows; ++y)
    for (int x = 0; x < band.cols; ++x) {
      if (!band.at<std::uint8_t>(y, x) || !strong_busy.at<std::uint8_t>(y, x)) continue;
      ++strong;
      const Eigen::Vector2d g(gx.at<float>(y, x), gy.at<float>(y, x)), t(dx.at<float>(y, x), dy.at<float>(y, x));
      if (t.norm() > 0.5 && std::abs(g.normalized().dot(t.normalized())) > 0.95) ++parallel;
    }
  EXPECT_GT(strong, 400);
  EXPECT_GT(parallel, strong / 3) << parallel << " of " << strong;
  // Static: the background away from the object is the same in a later frame.
  FrameInfo later;
  const cv::Mat busy10 = render(clu, m, traj, 10, &later);
  const cv::Mat away = off & (distance_to(later.object_mask) > 6.0);
  cv::Mat diff;
  cv::absdiff(busy, busy10, diff);
  EXPECT_EQ(cv::countNonZero(diff & away), 0);
  ::testing::Test::RecordProperty("clutter_band_edges", std::to_string(strong));
  ::testing::Test::RecordProperty("clutter_band_parallel", std::to_string(parallel));
}

TEST(Conditions, OccluderCoversUpTo40PercentAtMidSequenceAndNothingAtTheStart) {
  const model::Model m = flange();
  const auto traj = flange_trajectory();
  const Renderer reg(default_camera(), quiet(Condition::kRegular));
  const Renderer occ = renderer_for(quiet(Condition::kOcclusion), m, traj);
  for (const int f : {0, 1}) {
    FrameInfo info;
    (void)render(occ, m, traj, f, &info);
    EXPECT_EQ(fraction(info.occluder_mask, info.object_mask), 0.0) << "frame " << f;
  }
  double peak = 0.0;
  int peak_frame = -1;
  for (int f = 50; f <= 70; f += 2) {
    FrameInfo info;
    (void)render(occ, m, traj, f, &info);
    const double c = fraction(info.occluder_mask, info.object_mask);
    if (c > peak) {
      peak = c;
      peak_frame = f;
    }
  }
  EXPECT_GE(peak, 0.30);
  EXPECT_LE(peak, 0.45);
  // In front of the object: the occluded object pixels show the (textured) occluder.
  FrameInfo info;
  const cv::Mat covered = render(occ, m, traj, 60, &info), plain = render(reg, m, traj, 60);
  cv::Mat hidden, inner, diff;
  cv::erode(info.occluder_mask & info.object_mask, hidden, cv::Mat::ones(5, 5, CV_8U));
  ASSERT_GT(cv::countNonZero(hidden), 1000);
  cv::absdiff(covered, plain, diff);
  EXPECT_GT(cv::mean(diff, hidden)[0], 20.0);
  cv::erode(info.occluder_mask, inner, cv::Mat::ones(9, 9, CV_8U));
  cv::Scalar mean, sd;
  cv::meanStdDev(covered, mean, sd, inner);
  EXPECT_GT(sd[0], 5.0);
  // It moves: later it has left the place it covered at mid-sequence.
  FrameInfo late;
  (void)render(occ, m, traj, 110, &late);
  EXPECT_LT(fraction(late.occluder_mask, info.occluder_mask), 0.2);
  ::testing::Test::RecordProperty("occluder_peak_coverage", std::to_string(peak));
  ::testing::Test::RecordProperty("occluder_peak_frame", std::to_string(peak_frame));
}

TEST(Conditions, SpecularHighlightsSaturateSmallAreasOfTheObjectAndMove) {
  const model::Model m = flange();
  const auto traj = flange_trajectory();
  const Renderer reg(default_camera(), quiet(Condition::kRegular)), spec(default_camera(), quiet(Condition::kSpecular));
  int most = 0;
  std::vector<cv::Point2d> centroids;
  for (const int f : {0, 30, 60, 90}) {
    FrameInfo info;
    const cv::Mat s = render(spec, m, traj, f, &info), r = render(reg, m, traj, f);
    const int area = cv::countNonZero(info.object_mask);
    EXPECT_EQ(cv::countNonZero((r >= 254) & info.object_mask), 0) << "regular, frame " << f;
    const int saturated = cv::countNonZero((s >= 254) & info.object_mask);
    EXPECT_LT(saturated, area / 10) << "small areas, frame " << f;
    EXPECT_EQ(cv::countNonZero((s != r) & (distance_to(info.object_mask) > 1.5)), 0) << "on the object only";
    most = std::max(most, saturated);
    cv::Mat extra;
    cv::subtract(s, r, extra, cv::noArray(), CV_32F);
    const cv::Moments mo = cv::moments(extra);
    centroids.emplace_back(mo.m10 / mo.m00, mo.m01 / mo.m00);
  }
  EXPECT_GT(most, 100);
  // The highlight lobe moves with the pose (relative to the object's own motion of < 60 px).
  double spread = 0.0;
  for (const auto& c : centroids) spread = std::max(spread, cv::norm(c - centroids.front()));
  EXPECT_GT(spread, 10.0);
  ::testing::Test::RecordProperty("specular_max_saturated_px", std::to_string(most));
}

TEST(Conditions, MotionBlurWidensEdgesWithSpeed) {
  PinholeCamera cam = default_camera();
  cam.dist = {0, 0, 0, 0, 0};
  RenderOptions o = quiet(Condition::kBlur);
  o.texture_strength = 0.0;
  o.textured_background = false;
  const Renderer blur(cam, o);
  o.blur_samples = 1;
  const Renderer sharp(cam, o);
  const model::Model box = model::parse_cao(box_cao(), "box.cao").value();
  // Front face (y = -0.075) parallel to the image plane at 0.425 m; its left edge (x = -0.10)
  // projects to column cx + f * (-0.11 / 0.425).
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  const double depth = 0.425;
  const SE3 T(R, Eigen::Vector3d(-0.01, 0.0, 0.5));
  const double edge = cam.cx + cam.fx * (-0.11 / depth);
  const int row = 240;
  auto crossing = [&](const cv::Mat& img, double level, int x0, int x1) {
    for (int x = x0; x < x1; ++x) {
      const double a = img.at<std::uint8_t>(row, x), b = img.at<std::uint8_t>(row, x + 1);
      if (a < level && b >= level) return x + (level - a) / (b - a);
    }
    return std::nan("");
  };
  double prev_width = -1.0;
  for (const double motion_px : {0.0, 3.0, 6.0, 12.0}) {
    const SE3 T_prev(R, T.translation() - Eigen::Vector3d(motion_px * depth / cam.fx, 0.0, 0.0));
    const cv::Mat img = blur.render(box, T, 0, &T_prev);
    if (motion_px == 0.0) {
      EXPECT_LE(cv::norm(img, sharp.render(box, T, 0), cv::NORM_INF), 1.0);
    }
    const double lo = img.at<std::uint8_t>(row, static_cast<int>(edge) - 20);
    const double hi = img.at<std::uint8_t>(row, static_cast<int>(edge) + 10);
    ASSERT_GT(hi - lo, 40.0);
    const int x0 = static_cast<int>(edge - motion_px) - 6, x1 = static_cast<int>(edge) + 6;
    const double x10 = crossing(img, lo + 0.1 * (hi - lo), x0, x1), x90 = crossing(img, lo + 0.9 * (hi - lo), x0, x1);
    const double x50 = crossing(img, lo + 0.5 * (hi - lo), x0, x1);
    ASSERT_FALSE(std::isnan(x10) || std::isnan(x90) || std::isnan(x50));
    const double width = x90 - x10;
    // K = 5 sub-frames at 0.1, 0.3, ... 0.9 of the motion: a 10-90 % width of about 0.8 x motion.
    EXPECT_NEAR(width, 0.8 * motion_px + 0.6, 1.2) << motion_px << " px motion";
    // Centred on the pose at mid-exposure.
    EXPECT_NEAR(x50, edge - 0.5 * motion_px, 0.4) << motion_px << " px motion";
    EXPECT_GT(width, prev_width);
    prev_width = width;
  }
}

TEST(Conditions, FastTriplesTheInterFrameMotion) {
  TrajectorySpec spec;
  spec.T0 = geometry::look_at(0.6, -0.6, 0.75);
  const TrajectorySpec fast = trajectory_spec_for(Condition::kFast, spec);
  EXPECT_DOUBLE_EQ(fast.speed, 3.0 * spec.speed);
  auto mean_step = [](const std::vector<SE3>& t) {
    double s = 0.0;
    for (std::size_t i = 1; i < t.size(); ++i) s += (t[i].translation() - t[i - 1].translation()).norm();
    return s / static_cast<double>(t.size() - 1);
  };
  EXPECT_NEAR(mean_step(make_trajectory(fast)) / mean_step(make_trajectory(spec)), 3.0, 0.4);
}

TEST(Conditions, DeterministicForAGivenSeed) {
  const model::Model m = flange();
  for (const Condition c : all_conditions()) {
    const auto traj = flange_trajectory(c);
    RenderOptions o = options_for(c);
    o.cycle_frames = kFrames;
    const Renderer a = renderer_for(o, m, traj), b = renderer_for(o, m, traj);
    const cv::Mat ia = render(a, m, traj, 57), ib = render(b, m, traj, 57);
    EXPECT_EQ(cv::norm(ia, ib, cv::NORM_INF), 0.0) << condition_name(c);
    o.seed = 8;
    EXPECT_GT(cv::norm(ia, render(renderer_for(o, m, traj), m, traj, 57), cv::NORM_L1), 0.0) << condition_name(c);
  }
}

TEST(Conditions, OnePicturePerConditionAndRenderTimes) {
  const model::Model m = flange();
  // Frames that show each condition (light: brightest; shadow and occluder: over the object).
  const std::vector<std::pair<Condition, int>> shows{
      {Condition::kRegular, 0},   {Condition::kLight, 30},  {Condition::kShadow, 60},
      {Condition::kNoise, 0},     {Condition::kClutter, 0}, {Condition::kOcclusion, 60},
      {Condition::kSpecular, 90}, {Condition::kBlur, 60},   {Condition::kFast, 60}};
  for (const auto& [c, frame] : shows) {
    const auto traj = flange_trajectory(c);
    RenderOptions o = options_for(c);
    o.cycle_frames = kFrames;
    const Renderer r = renderer_for(o, m, traj);
    const auto t0 = std::chrono::steady_clock::now();
    for (int f = 50; f < 60; ++f) (void)render(r, m, traj, f);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / 10.0;
    ::testing::Test::RecordProperty("render_ms_" + std::string(condition_name(c)), std::to_string(ms));
    const cv::Mat img = render(r, m, traj, frame);
    ASSERT_EQ(img.type(), CV_8UC3);
    cv::imwrite("/tmp/synth2_" + std::string(condition_name(c)) + ".png", img);  // for a human look
  }
}

}  // namespace
}  // namespace v4r::synth
