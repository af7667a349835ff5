// v4r - robust model-based object tracking. MIT licence.
// The pose CSV of `v4r track` (poses.csv, and D/<object>.csv of a scene): header and rows.
#pragma once

#include <cstdio>

#include "v4r/geometry/se3.hpp"
#include "v4r/pipeline/vision_cycle.hpp"

namespace v4r::app {

/// The header line of a pose CSV (with its newline).
inline constexpr const char* kPoseCsvHeader =
    "frame,tx,ty,tz,qw,qx,qy,qz,cycle_ms,status,quality,features_visible,features_found,features_used,"
    "outliers,rms_px,lines_used,circle_points_used,junctions_used,degrade_level,"
    "f_tx,f_ty,f_tz,f_qw,f_qx,f_qy,f_qz,vx,vy,vz,wx,wy,wz,stamp_s,"
    "sigma_tx,sigma_ty,sigma_tz,sigma_rx,sigma_ry,sigma_rz,evidence\n";

/// \brief One row of a pose CSV: the pose (T_cam_obj for one camera, T_ref_obj in a scene), its
/// filtered value, velocity and covariance (translation m, rotation rad) in the same frame.
struct PoseCsvRow {
  int frame = 0;
  geometry::SE3 pose, filtered;
  geometry::Vector6d velocity = geometry::Vector6d::Zero();
  geometry::Matrix6d covariance = geometry::Matrix6d::Zero();
  double cycle_ms = 0.0;  ///< the whole cycle of the frame
  int features_used = 0;  ///< edges and circles kept by the solve (see features_used())
  int degrade_level = 0;
  double stamp_s = 0.0;
  const pipeline::ObjectReport* report = nullptr;
};

/// Edges and circles of one object that the pose solve kept (found, not rejected as outliers),
/// over all its views: `features_used` as the protocol's SystemStatus and the overlay count it.
/// The solver's observations are counted apart (lines_used, circle_points_used, junctions_used).
int features_used(const scene::Object& o);

/// Writes one row (the report must be set).
void write_pose_csv_row(std::FILE* f, const PoseCsvRow& r);

}  // namespace v4r::app
