// v4r - robust model-based object tracking. MIT licence.
#include "effects.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace v4r::synth::detail {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kOccluderMarginPx = 8.0;               ///< occluder clearance from the object at the start
constexpr double kOccluderTipBeyondPx = 10.0;           ///< tip centre beyond the object's far end along the arm
const Eigen::Vector3f kSleeve(150.0f, 128.0f, 112.0f);  ///< occluder base colour, BGR grey levels

Eigen::Vector3d unit_or(const Eigen::Vector3d& v, const Eigen::Vector3d& fallback) {
  return v.norm() > 0 ? Eigen::Vector3d(v.normalized()) : fallback;
}

/// Arm axis (base to tip, image up for tilt 0) and sweep direction for a tilt in degrees.
void arm_axes(double tilt_deg, Eigen::Vector2d& axis, Eigen::Vector2d& across) {
  const double t = std::clamp(tilt_deg, -80.0, 80.0) * kPi / 180.0;
  axis = Eigen::Vector2d(std::sin(t), -std::cos(t));
  across = Eigen::Vector2d(std::cos(t), std::sin(t));
}

/// Blends `colour` into bg where `canvas` (CV_8UC1 coverage) is set inside `box`, then clears it.
void blend_and_clear(cv::Mat& bg, cv::Mat& canvas, cv::Rect box, const cv::Vec3f& colour) {
  box &= cv::Rect(0, 0, bg.cols, bg.rows);
  for (int y = box.y; y < box.y + box.height; ++y) {
    auto* b = bg.ptr<cv::Vec3f>(y);
    auto* c = canvas.ptr<std::uint8_t>(y);
    for (int x = box.x; x < box.x + box.width; ++x) {
      if (c[x] == 0) continue;
      const float a = static_cast<float>(c[x]) * (1.0f / 255.0f);
      b[x] = b[x] * (1.0f - a) + colour * a;
      c[x] = 0;
    }
  }
}

/// A strong clutter colour: bright (165..235) or dark (5..30) grey with a slight tint.
cv::Vec3f strong_colour(std::uint64_t key, std::uint64_t i) {
  const bool bright = unit_hash(key, i) < 0.6;
  const double v = bright ? 165.0 + 70.0 * unit_hash(key, i + 1) : 5.0 + 25.0 * unit_hash(key, i + 1);
  const double tint = 8.0 * (unit_hash(key, i + 2) - 0.5);
  return cv::Vec3f(static_cast<float>(v - tint), static_cast<float>(v), static_cast<float>(v + tint));
}

constexpr int kShift = 4;  ///< fractional bits of the coordinates given to the OpenCV drawing functions
cv::Point fixed(double x, double y) {
  return {static_cast<int>(std::lround(x * (1 << kShift))), static_cast<int>(std::lround(y * (1 << kShift)))};
}

}  // namespace

double cycle_phase(const RenderOptions& opt, int frame) {
  const int p = cycle_frames(opt);
  const int t = ((frame % p) + p) % p;
  return static_cast<double>(t) / p;
}

FrameLighting lighting_at(const RenderOptions& opt, int frame) {
  FrameLighting L;
  L.light = unit_or(opt.light_dir_cam, Eigen::Vector3d(0, 0, -1));
  L.spec_light = unit_or(opt.specular.light_dir_cam, Eigen::Vector3d(0, -1, 0));
  L.specular = opt.specular.strength > 0.0;
  L.spec_strength = static_cast<float>(opt.specular.strength);
  L.shininess = static_cast<float>(std::max(opt.specular.shininess, 1.0));
  L.sheen = static_cast<float>(std::clamp(opt.specular.sheen, 0.0, 1.0));
  if (opt.light_change.enabled) {
    const double ph = 2.0 * kPi * cycle_phase(opt, frame);
    const double mid = 0.5 * (opt.light_change.gain_min + opt.light_change.gain_max);
    const double amp = 0.5 * (opt.light_change.gain_max - opt.light_change.gain_min);
    L.gain = static_cast<float>(std::max(0.0, mid + amp * std::sin(ph)));
    const double turn = opt.light_change.rotation_deg * kPi / 180.0 * 0.5 * (1.0 - std::cos(ph));
    const Eigen::Matrix3d Rz = Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    L.light = Rz * L.light;
    L.spec_light = Rz * L.spec_light;
  }
  return L;
}

ShadowState shadow_at(const RenderOptions& opt, int frame, int width, int height) {
  ShadowState s;
  if (!opt.shadow.enabled) return s;
  s.on = true;
  const double a = opt.shadow.angle_deg * kPi / 180.0;
  s.dx = std::cos(a);
  s.dy = std::sin(a);
  s.half = 0.5 * std::max(opt.shadow.width_px, 0.0);
  s.pen = std::max(opt.shadow.penumbra_px, 0.5);
  s.dark = static_cast<float>(std::clamp(opt.shadow.darkening, 0.0, 1.0));
  // Extent of the image along the sweep direction; the band enters at t = 0 and leaves at t -> P.
  double umin = 0, umax = 0;
  bool first = true;
  for (const auto& [x, y] : {std::pair{-0.5, -0.5}, std::pair{width - 0.5, -0.5}, std::pair{-0.5, height - 0.5},
                             std::pair{width - 0.5, height - 0.5}}) {
    const double u = s.dx * x + s.dy * y;
    umin = first ? u : std::min(umin, u);
    umax = first ? u : std::max(umax, u);
    first = false;
  }
  const double reach = s.half + s.pen;
  s.centre = umin - reach + (umax - umin + 2.0 * reach) * cycle_phase(opt, frame);
  return s;
}

Eigen::Vector3f OccluderState::colour(const float* texture, double along, double across) const {
  const double r = std::max(layout.radius_px, 1.0);
  const double rel = std::clamp(across / r, -1.0, 1.0);
  const double shade = 0.55 + 0.45 * std::sqrt(1.0 - rel * rel);  // a rounded sleeve lit from the front
  const double blotch = texture_at(texture, 0.35 * along + 97.0, 0.35 * across + 211.0);
  const double weave = texture_at(texture, 1.7 * along + 13.0, 1.7 * across + 5.0);
  const double v = shade * (0.8 + 0.3 * blotch + 0.15 * (weave - 0.5));
  return kSleeve * static_cast<float>(v);
}

OccluderState occluder_at(const RenderOptions& opt, const OccluderLayout& layout, int frame) {
  OccluderState s;
  if (!opt.occluder.enabled) return s;
  s.on = true;
  s.layout = layout;
  s.u = layout.u_start + (layout.u_end - layout.u_start) * cycle_phase(opt, frame);
  return s;
}

OccluderLayout default_occluder_layout(const Occluder& o, int width, int height) {
  OccluderLayout l;
  arm_axes(o.tilt_deg, l.axis, l.across);
  const Eigen::Vector2d centre(0.5 * (width - 1), 0.5 * (height - 1));
  l.radius_px = 0.08 * width;
  l.tip = l.axis.dot(centre) + 0.2 * height;
  const double u = l.across.dot(centre);
  l.u_start = u - 0.45 * width;
  l.u_end = u + 0.45 * width;
  return l;
}

OccluderLayout layout_occluder(const Occluder& o, const cv::Mat& mask_start, const cv::Mat& mask_peak) {
  OccluderLayout l = default_occluder_layout(o, mask_peak.cols, mask_peak.rows);
  if (cv::countNonZero(mask_peak) == 0) return l;
  // Histogram of the peak mask along the sweep direction (1 px bins), extents of both masks.
  double umin = 1e300, umax = -1e300, tip = -1e300, umin_start = 1e300;
  std::vector<Eigen::Vector2d> pts;
  for (int y = 0; y < mask_peak.rows; ++y) {
    const auto* m = mask_peak.ptr<std::uint8_t>(y);
    for (int x = 0; x < mask_peak.cols; ++x) {
      if (!m[x]) continue;
      const Eigen::Vector2d p(x, y);
      pts.push_back(p);
      umin = std::min(umin, l.across.dot(p));
      umax = std::max(umax, l.across.dot(p));
      tip = std::max(tip, l.axis.dot(p));
    }
  }
  for (int y = 0; y < mask_start.rows; ++y) {
    const auto* m = mask_start.ptr<std::uint8_t>(y);
    for (int x = 0; x < mask_start.cols; ++x) {
      if (!m[x]) continue;
      const Eigen::Vector2d p(x, y);
      umin_start = std::min(umin_start, l.across.dot(p));
      tip = std::max(tip, l.axis.dot(p));
    }
  }
  if (umin_start > 1e299) umin_start = umin;
  const int bins = static_cast<int>(std::ceil(umax - umin)) + 1;
  std::vector<long long> prefix(static_cast<std::size_t>(bins) + 1, 0);
  for (const Eigen::Vector2d& p : pts) ++prefix[static_cast<std::size_t>(std::floor(l.across.dot(p) - umin)) + 1];
  for (int i = 0; i < bins; ++i) prefix[static_cast<std::size_t>(i) + 1] += prefix[static_cast<std::size_t>(i)];
  const double target = std::clamp(o.peak_coverage, 0.0, 1.0) * static_cast<double>(pts.size());
  // Smallest band width (bins) whose best position covers the target; its best start.
  auto best = [&](int width, int& start) {
    long long m = -1;
    for (int b = 0; b + width <= bins; ++b) {
      const long long c = prefix[static_cast<std::size_t>(b + width)] - prefix[static_cast<std::size_t>(b)];
      if (c > m) {
        m = c;
        start = b;
      }
    }
    return static_cast<double>(m);
  };
  int lo = 1, hi = bins, start = 0;
  while (lo < hi) {
    const int mid = (lo + hi) / 2;
    if (best(mid, start) >= target)
      hi = mid;
    else
      lo = mid + 1;
  }
  best(lo, start);
  l.radius_px = 0.5 * lo;
  const double u_peak = umin + start + 0.5 * lo;
  l.tip = tip + kOccluderTipBeyondPx;
  // Clear of the object at the start (both at the start pose and at the peak pose), symmetric sweep.
  const double half = std::max(u_peak - (umin_start - l.radius_px - kOccluderMarginPx),
                               u_peak - (umin - l.radius_px - kOccluderMarginPx));
  l.u_start = u_peak - half;
  l.u_end = u_peak + half;
  return l;
}

void draw_random_clutter(cv::Mat& bg, const Clutter& c, std::uint32_t seed) {
  const std::uint64_t key = splitmix64(0xC1077E2000ull + seed);
  const int w = bg.cols, h = bg.rows;
  cv::Mat canvas = cv::Mat::zeros(h, w, CV_8UC1);
  std::uint64_t k = 0;
  auto rnd = [&] { return unit_hash(key, k++); };
  for (int i = 0; i < c.lines; ++i) {
    const double cx = rnd() * w, cy = rnd() * h, ang = rnd() * kPi, len = 40.0 + 220.0 * rnd();
    const int thick = 1 + static_cast<int>(rnd() * 3.99);
    const double ex = 0.5 * len * std::cos(ang), ey = 0.5 * len * std::sin(ang);
    cv::line(canvas, fixed(cx - ex, cy - ey), fixed(cx + ex, cy + ey), cv::Scalar(255), thick, cv::LINE_AA, kShift);
    const int r = static_cast<int>(std::ceil(0.5 * len)) + thick + 3;
    blend_and_clear(bg, canvas, cv::Rect(static_cast<int>(cx) - r, static_cast<int>(cy) - r, 2 * r + 1, 2 * r + 1),
                    strong_colour(key, 1000 + 3 * static_cast<std::uint64_t>(i)));
  }
  for (int i = 0; i < c.ellipses; ++i) {
    const double cx = rnd() * w, cy = rnd() * h, a = 8.0 + 62.0 * rnd(), b = 5.0 + 45.0 * rnd();
    const double ang = rnd() * 180.0;
    const bool filled = rnd() < 0.3;
    const int thick = filled ? cv::FILLED : 1 + static_cast<int>(rnd() * 2.99);
    cv::ellipse(canvas, fixed(cx, cy),
                cv::Size(static_cast<int>(a * (1 << kShift)), static_cast<int>(b * (1 << kShift))), ang, 0.0, 360.0,
                cv::Scalar(255), thick, cv::LINE_AA, kShift);
    const int r = static_cast<int>(std::ceil(std::max(a, b))) + 6;
    blend_and_clear(bg, canvas, cv::Rect(static_cast<int>(cx) - r, static_cast<int>(cy) - r, 2 * r + 1, 2 * r + 1),
                    strong_colour(key, 5000 + 3 * static_cast<std::uint64_t>(i)));
  }
}

void draw_near_clutter(cv::Mat& bg, const cv::Mat& mask, const Clutter& c, std::uint32_t seed) {
  if (c.near_lines <= 0 || cv::countNonZero(mask) == 0) return;
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  if (contours.empty()) return;
  const auto largest = std::max_element(contours.begin(), contours.end(), [](const auto& a, const auto& b) {
    return cv::contourArea(a) < cv::contourArea(b);
  });
  std::vector<cv::Point> poly;
  cv::approxPolyDP(*largest, poly, 2.0, true);
  struct Segment {
    Eigen::Vector2d a, b;
    double length;
  };
  std::vector<Segment> segments;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const cv::Point& p = poly[i];
    const cv::Point& q = poly[(i + 1) % poly.size()];
    const Eigen::Vector2d a(p.x, p.y), b(q.x, q.y);
    if ((b - a).norm() >= 30.0) segments.push_back({a, b, (b - a).norm()});
  }
  std::sort(segments.begin(), segments.end(), [](const Segment& s, const Segment& t) { return s.length > t.length; });
  cv::Mat inverse, dist;
  cv::compare(mask, 0, inverse, cv::CMP_EQ);
  cv::distanceTransform(inverse, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);  // pixels to the object

  const std::uint64_t key = splitmix64(0x2EA2C1077Eull + seed);
  cv::Mat canvas = cv::Mat::zeros(bg.rows, bg.cols, CV_8UC1);
  int drawn = 0;
  for (std::size_t i = 0; i < segments.size() && drawn < c.near_lines; ++i) {
    const Segment& s = segments[i];
    const Eigen::Vector2d dir = (s.b - s.a) / s.length, normal(-dir.y(), dir.x());
    const double off = c.near_min_px + (c.near_max_px - c.near_min_px) * unit_hash(key, 10 * i);
    const Eigen::Vector2d mid = 0.5 * (s.a + s.b);
    double side = 0.0;
    for (const double sg : {1.0, -1.0}) {
      const Eigen::Vector2d m = mid + sg * off * normal;
      const int mx = static_cast<int>(std::lround(m.x())), my = static_cast<int>(std::lround(m.y()));
      if (mx < 0 || my < 0 || mx >= bg.cols || my >= bg.rows) continue;
      if (dist.at<float>(my, mx) >= off - 4.0) {
        side = sg;
        break;
      }
    }
    if (side == 0.0) continue;
    const double s0 = 0.15 * unit_hash(key, 10 * i + 1), s1 = 0.15 * unit_hash(key, 10 * i + 2);
    const Eigen::Vector2d p0 = s.a + side * off * normal + dir * (s.length * s0);
    const Eigen::Vector2d p1 = s.b + side * off * normal - dir * (s.length * s1);
    const int thick = 2 + static_cast<int>(unit_hash(key, 10 * i + 3) * 1.99);
    cv::line(canvas, fixed(p0.x(), p0.y()), fixed(p1.x(), p1.y()), cv::Scalar(255), thick, cv::LINE_AA, kShift);
    const int x0 = static_cast<int>(std::min(p0.x(), p1.x())) - thick - 3;
    const int y0 = static_cast<int>(std::min(p0.y(), p1.y())) - thick - 3;
    const int x1 = static_cast<int>(std::max(p0.x(), p1.x())) + thick + 3;
    const int y1 = static_cast<int>(std::max(p0.y(), p1.y())) + thick + 3;
    blend_and_clear(bg, canvas, cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1), strong_colour(key, 10 * i + 4));
    ++drawn;
  }
}

}  // namespace v4r::synth::detail
