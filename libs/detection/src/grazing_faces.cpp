// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/grazing_faces.hpp"

#include <algorithm>
#include <cmath>

namespace v4r::detection {

GrazingFaces::GrazingFaces(const model::Model& model, double min_area_share) {
  const auto& J = model.junctions();
  for (const model::Face& f : model.faces()) {
    if (f.loop.size() < 3) continue;
    // The polygon's area (its vector area, projected on the normal) and the mean of its corners.
    Eigen::Vector3d c = Eigen::Vector3d::Zero(), a = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < f.loop.size(); ++i) {
      const Eigen::Vector3d& p = J[f.loop[i]].p;
      const Eigen::Vector3d& q = J[f.loop[(i + 1) % f.loop.size()]].p;
      c += p;
      a += p.cross(q);
    }
    c /= static_cast<double>(f.loop.size());
    const double area = 0.5 * std::abs(a.dot(f.normal));
    if (area > 0.0) faces_.push_back({c, f.normal, area});
  }
  std::sort(faces_.begin(), faces_.end(), [](const FaceInfo& x, const FaceInfo& y) { return x.area > y.area; });
  if (!faces_.empty()) {
    const double floor = min_area_share * faces_.front().area;
    faces_.erase(std::remove_if(faces_.begin(), faces_.end(), [&](const FaceInfo& f) { return f.area < floor; }), faces_.end());
  }
}

double GrazingFaces::seen_angle(const geometry::SE3& T, const FaceInfo& f) {
  const Eigen::Vector3d nc = T.rotation() * f.normal;
  const Eigen::Vector3d to_camera = -(T * f.centroid).normalized();
  return std::asin(std::clamp(nc.dot(to_camera), -1.0, 1.0));
}

std::size_t GrazingFaces::unfold(const geometry::SE3& T, const Eigen::Vector3d& pivot_obj, double band_rad, double seen_rad,
                                 std::span<geometry::SE3> out) const {
  std::size_t n = 0;
  const Eigen::Matrix3d R = T.rotation();
  const Eigen::Vector3d pivot = T * pivot_obj;
  for (const FaceInfo& f : faces_) {
    if (n >= out.size()) break;
    const double seen = seen_angle(T, f);
    if (seen < -band_rad || seen >= seen_rad) continue;
    // (A face within the band is never seen square on: the normal and the line of sight differ.)
    const Eigen::Vector3d cross = (R * f.normal).cross(-(T * f.centroid));
    if (!(cross.norm() > 1e-12)) continue;
    const Eigen::Vector3d axis = cross.normalized();
    // The turn about the pivot moves the face's centre and so the line of sight to it: the angle
    // is corrected by what is still missing, a few times.
    double angle = seen_rad - seen;
    geometry::SE3 Tt = T;
    for (int it = 0; it < 4; ++it) {
      const Eigen::Matrix3d turn = Eigen::AngleAxisd(angle, axis).toRotationMatrix();
      Tt = geometry::SE3(Eigen::Matrix3d(turn * R), turn * (T.translation() - pivot) + pivot);
      angle += seen_rad - seen_angle(Tt, f);
    }
    out[n++] = Tt;
  }
  return n;
}

}  // namespace v4r::detection
