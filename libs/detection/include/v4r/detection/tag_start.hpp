// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <array>
#include <memory>
#include <string>

#include "v4r/core/expected.hpp"
#include "v4r/core/params.hpp"
#include "v4r/detection/tag_spec.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/image/image_view.hpp"

struct apriltag_detector;  // libapriltag (C)
struct apriltag_family;

namespace v4r::detection {

/// \brief How the tag is looked for (libapriltag's detector settings and acceptance limits).
/// Registered as `search.tag.*` (add_tag_params).
struct TagParams {
  double decimate = 2.0;   ///< quads are found on the image shrunk by this factor (1: full resolution)
  double blur_px = 0.0;    ///< Gaussian blur (sigma, px) before finding quads (0: none; 0.8 for noisy images)
  int max_hamming = 1;     ///< bit errors corrected when decoding (0..2; more: more false tags)
  double min_margin = 15.0;  ///< libapriltag's decision margin a detection needs (grey levels of the bit contrast)
  /// Pixels: while the tag is seen, an object pose is accepted only if it puts the tag's corners
  /// within this distance of the seen ones (TagStart::corner_offset_px).
  double max_offset_px = 10.0;
};

/// Registers every TagParams field under `prefix` (e.g. "search.tag") with unit and range.
void add_tag_params(ParamRegistry& r, TagParams& p, const std::string& prefix = "search.tag");

/// \brief The tag of a TagSpec found in one image, and the two object poses it allows.
///
/// A planar square seen in perspective fits two poses (reflected about the line of sight: the
/// IPPE ambiguity); both are given, best corner fit first, and the edge test of the whole model
/// decides between them.
struct TagObservation {
  bool found = false;
  std::array<Eigen::Vector2d, 4> corners_px{};  ///< libapriltag's corners, pixels (distorted image)
  int hamming = 0;                              ///< bits corrected
  double margin = 0.0;                          ///< decision margin
  int poses = 0;                                ///< valid entries of T_cam_obj (0..2)
  std::array<geometry::SE3, 2> T_cam_obj{};     ///< T_cam_tag * T_obj_tag^-1, both IPPE solutions
  std::array<double, 2> rms_px{};               ///< RMS corner reprojection error of each, pixels
};

/// \brief Finds an AprilTag fixed on the object and turns it into object pose hypotheses
/// (issue 10, optional fiducial start). The tracker verifies them against the model's edges and
/// tracks markerless from then on: the tag is only looked for while the object is searched.
///
/// \code
///   auto tag = TagStart::create(spec, camera, params);  // set-up: allocates, checks the id
///   TagObservation o = (*tag)->detect(grey);            // o.T_cam_obj[0 .. o.poses)
/// \endcode
/// detect() throws nothing; it allocates (inside libapriltag and cv::solvePnPGeneric), so it
/// belongs to search frames, never to the tracking cycle. Not thread-safe.
class TagStart {
 public:
  /// An error names the field of the spec that is wrong (an id beyond the family's codes).
  static Expected<std::unique_ptr<TagStart>> create(const TagSpec& spec, const geometry::PinholeCamera& cam,
                                                    const TagParams& p);
  ~TagStart();
  TagStart(const TagStart&) = delete;
  TagStart& operator=(const TagStart&) = delete;

  /// Looks for the tag in an 8-bit grey image of the camera's size (another size: not found).
  /// Tags of other ids or families are ignored; of several with the spec's id, the clearest.
  TagObservation detect(const image::ImageView& grey);

  /// How far pose T_cam_obj puts the tag from where `o` saw it: the largest distance between a
  /// projected tag corner and the seen one, pixels; infinite when that pose shows the tag's back
  /// or puts a corner behind the camera. A pose of the object must explain a tag seen on it.
  [[nodiscard]] double corner_offset_px(const TagObservation& o, const geometry::SE3& T_cam_obj) const;

  [[nodiscard]] const TagSpec& spec() const { return spec_; }

 private:
  TagStart(const TagSpec& spec, const geometry::PinholeCamera& cam, const TagParams& p);
  TagSpec spec_;
  geometry::SE3 T_tag_obj_;
  geometry::PinholeCamera cam_;
  TagParams p_;
  apriltag_family* family_ = nullptr;
  apriltag_detector* detector_ = nullptr;
};

}  // namespace v4r::detection
