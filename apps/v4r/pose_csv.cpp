// v4r - robust model-based object tracking. MIT licence.
#include "pose_csv.hpp"

#include <string>

#include <fmt/format.h>

#include "v4r/io/pose_io.hpp"

namespace v4r::app {

int features_used(const scene::Object& o) {
  int n = 0;
  for (const scene::View& v : o.views) {
    for (const scene::LineFeature& f : v.lines)
      if (f.visible && !f.ambiguous && !f.dropped && f.status == scene::FeatureStatus::kFound) ++n;
    for (const scene::ArcFeature& a : v.arcs)
      if (a.visible && !a.dropped && a.status == scene::FeatureStatus::kFound) ++n;
  }
  return n;
}

void write_pose_csv_row(std::FILE* f, const PoseCsvRow& r) {
  const pipeline::ObjectReport& rep = *r.report;
  // A frame without a pose (`searching`) has its pose fields empty.
  std::string p1 = ",,,,,,", p2 = ",,,,,,,,,,,,", p3 = ",,,,,";
  if (rep.status != scene::TrackStatus::kSearching) {
    const Eigen::Quaterniond q = io::canonical(r.pose.quaternion());
    const Eigen::Vector3d t = r.pose.translation();
    const Eigen::Quaterniond fq = io::canonical(r.filtered.quaternion());
    const Eigen::Vector3d ft = r.filtered.translation();
    const geometry::Vector6d& v = r.velocity;
    const geometry::Vector6d sd = r.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    p1 = fmt::format("{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}", t.x(), t.y(), t.z(), q.w(), q.x(), q.y(), q.z());
    p2 = fmt::format("{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g}", ft.x(),
                     ft.y(), ft.z(), fq.w(), fq.x(), fq.y(), fq.z(), v[0], v[1], v[2], v[3], v[4], v[5]);
    p3 = fmt::format("{:.4g},{:.4g},{:.4g},{:.4g},{:.4g},{:.4g}", sd[0], sd[1], sd[2], sd[3], sd[4], sd[5]);
  }
  std::fprintf(f, "%d,%s,%.4f,%s,%.3f,%d,%d,%d,%d,%.3f,%d,%d,%d,%d,%s,%.6f,%s,%.3f\n", r.frame, p1.c_str(), r.cycle_ms,
               scene::to_string(rep.status), rep.quality, rep.features_visible, rep.features_found, r.features_used,
               rep.outliers, rep.rms_px, rep.lines_used, rep.circle_points_used, rep.junctions_used, r.degrade_level,
               p2.c_str(), r.stamp_s, p3.c_str(), rep.evidence);
}

}  // namespace v4r::app
