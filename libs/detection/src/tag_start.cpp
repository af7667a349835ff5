// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/tag_start.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include <apriltag/apriltag.h>
#include <apriltag/common/image_u8.h>
#include <apriltag/common/zarray.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>
#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace v4r::detection {

namespace {

struct FamilyFns {
  const char* name;
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

constexpr FamilyFns kFamilies[] = {
    {"tag36h11", tag36h11_create, tag36h11_destroy},
    {"tag36h10", tag36h10_create, tag36h10_destroy},
    {"tag25h9", tag25h9_create, tag25h9_destroy},
    {"tag16h5", tag16h5_create, tag16h5_destroy},
    {"tagStandard41h12", tagStandard41h12_create, tagStandard41h12_destroy},
    {"tagStandard52h13", tagStandard52h13_create, tagStandard52h13_destroy},
    {"tagCircle21h7", tagCircle21h7_create, tagCircle21h7_destroy},
    {"tagCircle49h12", tagCircle49h12_create, tagCircle49h12_destroy},
    {"tagCustom48h12", tagCustom48h12_create, tagCustom48h12_destroy},
};

const FamilyFns* find_family(const std::string& name) {
  for (const FamilyFns& f : kFamilies)
    if (name == f.name) return &f;
  return nullptr;
}

}  // namespace

void add_tag_params(ParamRegistry& r, TagParams& p, const std::string& prefix) {
  r.add(prefix + ".decimate", &p.decimate, 1.0, 8.0, "",
        "with --tag: the tag's outline is found on the image shrunk by this factor (1: full resolution, slower)");
  r.add(prefix + ".blur", &p.blur_px, 0.0, 5.0, "px", "with --tag: Gaussian blur (sigma) before finding the outline (0: none)");
  r.add(prefix + ".max_hamming", &p.max_hamming, 0, 2, "bits", "with --tag: bit errors corrected when decoding a tag");
  r.add(prefix + ".min_margin", &p.min_margin, 0.0, 255.0, "grey",
        "with --tag: decision margin (bit contrast) a detected tag needs");
  r.add(prefix + ".max_offset", &p.max_offset_px, 0.0, 10000.0, "px",
        "with --tag: while the tag is seen, a found pose must put its corners this close to the seen ones");
}

Expected<std::unique_ptr<TagStart>> TagStart::create(const TagSpec& spec, const geometry::PinholeCamera& cam,
                                                     const TagParams& p) {
  const FamilyFns* f = find_family(spec.family);
  if (!f) return make_error(fmt::format("tag: field 'family': unknown tag family '{}'", spec.family));
  if (!(spec.size_m > 0.0)) return make_error(fmt::format("tag: field 'size_m': {} is not a size (> 0 m)", spec.size_m));
  if (cam.width <= 0 || cam.height <= 0 || !(cam.fx > 0.0) || !(cam.fy > 0.0))
    return make_error("tag: the camera has no image size or focal length");
  std::unique_ptr<TagStart> t(new TagStart(spec, cam, p));
  t->family_ = f->create();
  if (!t->family_) return make_error(fmt::format("tag: libapriltag could not create family '{}'", spec.family));
  if (spec.id < 0 || static_cast<std::uint32_t>(spec.id) >= t->family_->ncodes)
    return make_error(fmt::format("tag: field 'id': {} is not in family {} (ids 0..{})", spec.id, spec.family,
                                  t->family_->ncodes - 1));
  t->detector_ = apriltag_detector_create();
  if (!t->detector_) return make_error("tag: libapriltag could not create a detector");
  apriltag_detector_add_family_bits(t->detector_, t->family_, std::clamp(p.max_hamming, 0, 2));
  t->detector_->nthreads = 1;
  t->detector_->quad_decimate = static_cast<float>(std::clamp(p.decimate, 1.0, 8.0));
  t->detector_->quad_sigma = static_cast<float>(std::clamp(p.blur_px, 0.0, 5.0));
  t->detector_->refine_edges = true;
  return t;
}

TagStart::TagStart(const TagSpec& spec, const geometry::PinholeCamera& cam, const TagParams& p)
    : spec_(spec), T_tag_obj_(spec.T_obj_tag.inverse()), cam_(cam), p_(p) {}

TagStart::~TagStart() {
  if (detector_) apriltag_detector_destroy(detector_);
  if (family_)
    if (const FamilyFns* f = find_family(spec_.family)) f->destroy(family_);
}

double TagStart::corner_offset_px(const TagObservation& o, const geometry::SE3& T_cam_obj) const {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  if (!o.found) return kInf;
  const geometry::SE3 T_cam_tag = T_cam_obj * spec_.T_obj_tag;
  if (!(T_cam_tag.rotation().col(2).dot(T_cam_tag.translation()) > 0.0)) return kInf;  // its back faces the camera
  const double h = 0.5 * spec_.size_m;
  const double xs[4] = {-h, h, h, -h}, ys[4] = {h, h, -h, -h};  // libapriltag's corner order (see detect)
  double worst = 0.0;
  for (std::size_t k = 0; k < 4; ++k) {
    const Eigen::Vector3d p = T_cam_tag * Eigen::Vector3d(xs[k], ys[k], 0.0);
    if (!(p.z() > 1e-6)) return kInf;
    worst = std::max(worst, (cam_.project(p) - o.corners_px[k]).norm());
  }
  return worst;
}

TagObservation TagStart::detect(const image::ImageView& grey) {
  TagObservation o;
  if (grey.empty() || grey.width != cam_.width || grey.height != cam_.height || !detector_) return o;
  // libapriltag reads the image only (its type has no const).
  image_u8_t im{grey.width, grey.height, grey.stride, const_cast<std::uint8_t*>(grey.data)};
  zarray_t* dets = apriltag_detector_detect(detector_, &im);
  if (!dets) return o;
  const apriltag_detection_t* best = nullptr;
  for (int i = 0; i < zarray_size(dets); ++i) {
    apriltag_detection_t* d = nullptr;
    zarray_get(dets, i, &d);
    if (!d || d->id != spec_.id || d->hamming > p_.max_hamming || d->decision_margin < p_.min_margin) continue;
    if (!best || d->decision_margin > best->decision_margin) best = d;
  }
  if (best) {
    o.found = true;
    o.hamming = best->hamming;
    o.margin = best->decision_margin;
    // libapriltag puts pixel centres at +0.5 (pixel (0,0) covers [0,1]^2); v4r at integers.
    for (int k = 0; k < 4; ++k)
      o.corners_px[static_cast<std::size_t>(k)] = Eigen::Vector2d(best->p[k][0] - 0.5, best->p[k][1] - 0.5);
  }
  apriltag_detections_destroy(dets);
  if (!o.found) return o;
  // libapriltag's corners wrap the tag at (-1, 1), (1, 1), (1, -1), (-1, -1) of its homography's
  // frame, whose y is the printed bitmap's rows (down): in the tag frame (x right, y down) these
  // are the corners OpenCV's SOLVEPNP_IPPE_SQUARE expects in this order. Corners are undistorted
  // to normalised coordinates first, so the solve has an ideal unit camera.
  const double h = 0.5 * spec_.size_m;
  std::array<cv::Point3d, 4> obj{cv::Point3d(-h, h, 0), cv::Point3d(h, h, 0), cv::Point3d(h, -h, 0),
                                       cv::Point3d(-h, -h, 0)};
  std::array<cv::Point2d, 4> img;
  for (std::size_t k = 0; k < 4; ++k) {
    const Eigen::Vector2d n = cam_.pixel_to_normalized(o.corners_px[k]);
    img[k] = cv::Point2d(n.x(), n.y());
  }
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat errors;
  int n = 0;
  try {
    n = cv::solvePnPGeneric(cv::Mat(4, 1, CV_64FC3, obj.data()), cv::Mat(4, 1, CV_64FC2, img.data()),
                            cv::Matx33d::eye(), cv::noArray(), rvecs, tvecs, false, cv::SOLVEPNP_IPPE_SQUARE,
                            cv::noArray(), cv::noArray(), errors);
  } catch (const cv::Exception&) {
    n = 0;  // a degenerate quad: no pose
  }
  for (int k = 0; k < n && o.poses < 2; ++k) {
    const cv::Vec3d r = rvecs[static_cast<std::size_t>(k)], t = tvecs[static_cast<std::size_t>(k)];
    if (!(t[2] > 0.0)) continue;  // behind the camera
    const geometry::SE3 T_cam_tag = geometry::SE3::from_rvec(Eigen::Vector3d(t[0], t[1], t[2]), Eigen::Vector3d(r[0], r[1], r[2]));
    const auto j = static_cast<std::size_t>(o.poses++);
    o.T_cam_obj[j] = T_cam_tag * T_tag_obj_;
    o.rms_px[j] = errors.empty() ? 0.0 : errors.at<double>(k) * cam_.focal();
  }
  o.found = o.poses > 0;
  return o;
}

}  // namespace v4r::detection
