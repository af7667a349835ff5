// v4r - robust model-based object tracking. MIT licence.
// Test scenes for the AprilTag start (shared by the unit tests and tests/tag_start_test.cpp): a
// tag bitmap made from libapriltag's family codes, pasted in perspective onto a rendered image.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdlib>

#include <apriltag/apriltag.h>
#include <apriltag/common/image_u8.h>
#include <apriltag/tag36h11.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "v4r/detection/tag_spec.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"

namespace v4r::detection::scenes {

/// \brief A tag36h11 bitmap (white margin included, one byte per cell) and its geometry.
struct TagBitmap {
  cv::Mat cells;         ///< CV_8U, total_width x total_width cells, 0 black, 255 white
  int border_cells = 8;  ///< cells across the black border square (the tag's size)
};

/// The bitmap of tag36h11 id `id`, from libapriltag's own codes (apriltag_to_image).
inline TagBitmap tag36h11_bitmap(int id) {
  apriltag_family_t* fam = tag36h11_create();
  image_u8_t* im = apriltag_to_image(fam, id);
  TagBitmap b;
  b.cells = cv::Mat(im->height, im->width, CV_8U);
  for (int y = 0; y < im->height; ++y)
    for (int x = 0; x < im->width; ++x) b.cells.at<std::uint8_t>(y, x) = im->buf[y * im->stride + x];
  b.border_cells = static_cast<int>(fam->width_at_border);
  // (image_u8_destroy is in libapriltag-utils; the image is two calloc'ed blocks.)
  std::free(im->buf);
  std::free(im);
  tag36h11_destroy(fam);
  return b;
}

/// True when the tag's printed side faces the camera (its z axis, into the surface, points away).
inline bool tag_faces_camera(const geometry::SE3& T_cam_tag) {
  return T_cam_tag.rotation().col(2).dot(T_cam_tag.translation()) > 0.0;
}

/// Pastes the tag (and, with `card_m` > 0, a white square card of that edge around it, in the
/// tag's plane) into `img` (BGR or grey, 8-bit) at T_cam_tag, in perspective, with anti-aliased
/// cell edges. Black cells get grey level `dark`, white ones `light`.
inline void paint_tag(cv::Mat& img, const TagBitmap& b, double size_m, const geometry::SE3& T_cam_tag,
                      const geometry::PinholeCamera& cam, double card_m = 0.0, int dark = 25, int light = 225) {
  const int total = b.cells.cols;
  const double cell = size_m / b.border_cells;
  constexpr int kUp = 24;  // bitmap pixels per cell (so the warp's linear filter blurs only cell edges)
  const auto project_quad = [&](double half) {
    // Corners of a square of half-edge `half` in the tag plane: top-left, top-right, bottom-right, bottom-left.
    std::array<cv::Point2f, 4> q;
    const double xs[4] = {-half, half, half, -half}, ys[4] = {-half, -half, half, half};
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d p = cam.project(T_cam_tag * Eigen::Vector3d(xs[k], ys[k], 0.0));
      q[static_cast<std::size_t>(k)] = cv::Point2f(static_cast<float>(p.x()), static_cast<float>(p.y()));
    }
    return q;
  };
  const auto blend = [&](const cv::Mat& src, double half, int fill_value, bool use_src) {
    cv::Mat tex;
    const int n = use_src ? total * kUp : 64;
    if (use_src) {
      cv::resize(src, tex, cv::Size(n, n), 0, 0, cv::INTER_NEAREST);
      tex = tex / 255.0 * (light - dark) + dark;
    } else {
      tex = cv::Mat(n, n, CV_8U, cv::Scalar(fill_value));
    }
    const std::array<cv::Point2f, 4> dst = project_quad(half);
    // Source corners: the outer edges of the bitmap (pixel centres at integer coordinates).
    const std::array<cv::Point2f, 4> srcq{cv::Point2f(-0.5f, -0.5f), cv::Point2f(n - 0.5f, -0.5f),
                                          cv::Point2f(n - 0.5f, n - 0.5f), cv::Point2f(-0.5f, n - 0.5f)};
    const cv::Mat H = cv::getPerspectiveTransform(srcq.data(), dst.data());
    cv::Mat warped, alpha;
    cv::warpPerspective(tex, warped, H, img.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::warpPerspective(cv::Mat(n, n, CV_32F, cv::Scalar(1.0f)), alpha, H, img.size(), cv::INTER_LINEAR,
                        cv::BORDER_CONSTANT, cv::Scalar(0));
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const float a = alpha.at<float>(y, x);
        if (a <= 0.0f) continue;
        const float v = warped.at<std::uint8_t>(y, x);  // already a * value at the edge (border 0)
        if (img.channels() == 3) {
          cv::Vec3b& p = img.at<cv::Vec3b>(y, x);
          for (int c = 0; c < 3; ++c) p[c] = cv::saturate_cast<std::uint8_t>(p[c] * (1.0f - a) + v);
        } else {
          std::uint8_t& p = img.at<std::uint8_t>(y, x);
          p = cv::saturate_cast<std::uint8_t>(p * (1.0f - a) + v);
        }
      }
  };
  if (card_m > 0.0) blend(cv::Mat(), 0.5 * card_m, light, false);
  blend(b.cells, 0.5 * cell * total, 0, true);
}

/// Sensor noise (Gaussian, sigma grey levels) over the whole image, seeded.
inline void add_noise(cv::Mat& img, double sigma, std::uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat n(img.size(), CV_MAKETYPE(CV_16S, img.channels()));
  rng.fill(n, cv::RNG::NORMAL, 0.0, sigma);
  cv::Mat wide;
  img.convertTo(wide, CV_16S);
  wide += n;
  wide.convertTo(img, img.type());
}

}  // namespace v4r::detection::scenes
