// v4r - robust model-based object tracking. MIT licence.
#include "pose_csv.hpp"

#include "v4r/io/pose_io.hpp"

namespace v4r::app {

void write_pose_csv_row(std::FILE* f, const PoseCsvRow& r) {
  const pipeline::ObjectReport& rep = *r.report;
  const Eigen::Quaterniond q = io::canonical(r.pose.quaternion());
  const Eigen::Vector3d t = r.pose.translation();
  const Eigen::Quaterniond fq = io::canonical(r.filtered.quaternion());
  const Eigen::Vector3d ft = r.filtered.translation();
  const geometry::Vector6d& v = r.velocity;
  const geometry::Vector6d sd = r.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  std::fprintf(f,
               "%d,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.4f,%s,%.3f,%d,%d,%d,%d,%.3f,%d,%d,%d,%d,"
               "%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6f,%.4g,%.4g,%.4g,%.4g,%.4g,%.4g,%.3f\n",
               r.frame, t.x(), t.y(), t.z(), q.w(), q.x(), q.y(), q.z(), r.cycle_ms, scene::to_string(rep.status),
               rep.quality, rep.features_visible, rep.features_found, r.features_used, rep.outliers, rep.rms_px,
               rep.lines_used, rep.circle_points_used, rep.junctions_used, r.degrade_level, ft.x(), ft.y(), ft.z(),
               fq.w(), fq.x(), fq.y(), fq.z(), v[0], v[1], v[2], v[3], v[4], v[5], r.stamp_s, sd[0], sd[1], sd[2],
               sd[3], sd[4], sd[5], rep.evidence);
}

}  // namespace v4r::app
