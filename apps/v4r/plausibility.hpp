// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <string>
#include <vector>

#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/model.hpp"

namespace v4r::app {

/// \brief Inputs that are valid but almost certainly a mistake of units or angles. Each check
/// returns warnings (one line each, without a prefix); none changes anything.
namespace plausibility {
inline constexpr double kMaxRotationVector = 6.283185307179586;  ///< rad: longer is "degrees?"
inline constexpr double kMaxDistance = 20.0;                     ///< m: farther is "millimetres?"
inline constexpr double kMinDistance = 0.01;                     ///< m: nearer is implausible
inline constexpr double kMaxModelSize = 10.0;                    ///< m: a larger model is "millimetres?"
inline constexpr double kMinImageSize = 20.0;                    ///< px: a smaller projection cannot be tracked
}  // namespace plausibility

/// The initial pose as given: the rotation vector's length and the distance.
std::vector<std::string> check_pose(const io::PoseNumbers& pose, const std::string& source);

/// The model's largest extent (bounding box of its junctions, circles and cylinders).
std::vector<std::string> check_model_size(const model::Model& m, const std::string& source);

/// Where the model lands in the image at pose T: outside it, or fewer than kMinImageSize pixels.
std::vector<std::string> check_projection(const model::Model& m, const geometry::PinholeCamera& cam,
                                          const geometry::SE3& T);

/// Axis-aligned bounding box of the model (junctions, circles, cylinders) in metres.
struct Extent {
  Eigen::Vector3d min = Eigen::Vector3d::Zero(), max = Eigen::Vector3d::Zero();
  [[nodiscard]] Eigen::Vector3d size() const { return max - min; }
};
Extent model_extent(const model::Model& m);

}  // namespace v4r::app
