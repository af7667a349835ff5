// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/se3.hpp"

namespace v4r::detection {

/// \brief An AprilTag fixed on the object (issue 10, optional fiducial start): which tag, its
/// size and where it sits on the object.
///
/// Tag frame (AprilTag's): origin at the centre of the tag, x to the right and y down as the tag
/// is printed (its bitmap's columns and rows), z = x cross y into the tag, i.e. into the surface
/// it is stuck on when seen from the front.
struct TagSpec {
  std::string family;  ///< libapriltag family name, e.g. "tag36h11" (see tag_families())
  int id = 0;          ///< tag id within the family
  /// Metres: edge of the tag's black border square, outer edge to outer edge (for tag36h11 the
  /// 8 of its 10 cells inside the white margin).
  double size_m = 0.0;
  geometry::SE3 T_obj_tag;  ///< tag frame -> object frame
};

/// The family names libapriltag provides (tag36h11, tag25h9, tag16h5, ...).
const std::vector<std::string>& tag_families();

/// \brief Parses `family:id:size_m:tx ty tz rx ry rz` (T_obj_tag: metres, rotation vector in
/// radians; commas are accepted between the six numbers). An error names the field (family, id,
/// size_m, tx .. rz) and what is wrong; `source` names the input (e.g. "--tag").
Expected<TagSpec> parse_tag_spec(std::string_view text, const std::string& source);

/// The text parse_tag_spec reads back to `spec` (to within the printed precision).
std::string format_tag_spec(const TagSpec& spec);

}  // namespace v4r::detection
