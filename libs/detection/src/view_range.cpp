// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/view_range.hpp"

#include <algorithm>
#include <cmath>

namespace v4r::detection {

geometry::SE3 on_axis(const geometry::SE3& T, const Eigen::Vector3d& centre) {
  const Eigen::Vector3d c_cam = T * centre;
  return geometry::SE3(Eigen::Quaterniond::FromTwoVectors(c_cam.normalized(), Eigen::Vector3d::UnitZ()), Eigen::Vector3d::Zero()) * T;
}

bool in_view_range(const ViewRange& v, const Eigen::Vector3d& centre, std::span<const geometry::SE3> symmetries,
                   const geometry::SE3& T, double m, double m_inplane) {
  constexpr double kDeg = 3.14159265358979323846 / 180.0;
  const double dist_ratio = 1.0 + m / 45.0;
  // The camera turned about its centre until the model's centre lies on the optical axis (as the
  // template views are made): the in-plane turn of an object seen off the axis is then its own.
  if (!((T * centre).norm() > 1e-12)) return false;
  const geometry::SE3 T_axis = on_axis(T, centre);
  for (const geometry::SE3& S : symmetries) {
    const geometry::SE3 TS = T_axis * S;
    const Eigen::Vector3d eye = TS.inverse().translation() - centre;
    const double d = eye.norm();
    if (d < v.distance_min_m / dist_ratio || d > v.distance_max_m * dist_ratio) continue;
    const double el = std::asin(std::clamp(eye.z() / std::max(d, 1e-12), -1.0, 1.0)) / kDeg;
    if (el < v.elevation_min_deg - m || el > v.elevation_max_deg + m) continue;
    // In-plane turn: where the object's z axis points in the image (up at 0, see geometry::look_at).
    const Eigen::Vector3d z = TS.rotation().col(2);
    if (std::hypot(z.x(), z.y()) > 0.2) {  // (seen from straight above, the turn is the azimuth's)
      const double ip = std::atan2(z.x(), -z.y()) / kDeg;
      if (ip < v.inplane_min_deg - m_inplane || ip > v.inplane_max_deg + m_inplane) continue;
    }
    return true;
  }
  return false;
}

}  // namespace v4r::detection
