// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/view_range.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "degrees.hpp"
#include "v4r/geometry/look_at.hpp"

using namespace v4r;
using namespace v4r::detection;

namespace {

/// A camera at `el` / `az` degrees, `d` metres from `c`, turned `ip` degrees about its axis, then
/// turned about its centre so that `c` is seen `off` degrees right of and below the axis.
geometry::SE3 view(double el, double az, double ip, double d, const Eigen::Vector3d& c, double off = 0.0) {
  const geometry::SE3 T0 = geometry::SE3::from_rvec(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, ip * kDeg)) *
                           geometry::look_at(d, az * kDeg, el * kDeg, c);
  const Eigen::Vector3d ray = Eigen::Vector3d(std::tan(off * kDeg), std::tan(off * kDeg), 1.0).normalized();
  return geometry::SE3(Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), ray), Eigen::Vector3d::Zero()) * T0;
}

ViewRange range() {
  ViewRange r;  // elevation 15..75, in-plane -30..30
  r.distance_min_m = 0.5;
  r.distance_max_m = 1.0;
  return r;
}

}  // namespace

TEST(ViewRange, ElevationDistanceAndInPlaneTurnAreTestedWithTheirMargins) {
  const Eigen::Vector3d c(0.01, -0.02, 0.03);
  const std::vector<geometry::SE3> id{geometry::SE3()};
  const ViewRange r = range();
  EXPECT_TRUE(in_view_range(r, c, id, view(40, 70, 10, 0.7, c), 5, 15));
  // Elevation: 12 deg is inside 15 - 5, 8 deg is not; 79 inside 75 + 5, 81 not.
  EXPECT_TRUE(in_view_range(r, c, id, view(12, 70, 10, 0.7, c), 5, 15));
  EXPECT_FALSE(in_view_range(r, c, id, view(8, 70, 10, 0.7, c), 5, 15));
  EXPECT_TRUE(in_view_range(r, c, id, view(79, 70, 10, 0.7, c), 5, 15));
  EXPECT_FALSE(in_view_range(r, c, id, view(81, 70, 10, 0.7, c), 5, 15));
  // Distance: widened by 1 + 5 / 45.
  EXPECT_TRUE(in_view_range(r, c, id, view(40, 70, 10, 1.1, c), 5, 15));
  EXPECT_FALSE(in_view_range(r, c, id, view(40, 70, 10, 1.12, c), 5, 15));
  EXPECT_TRUE(in_view_range(r, c, id, view(40, 70, 10, 0.46, c), 5, 15));
  EXPECT_FALSE(in_view_range(r, c, id, view(40, 70, 10, 0.44, c), 5, 15));
  // In-plane turn, with its own margin.
  EXPECT_TRUE(in_view_range(r, c, id, view(40, 70, -43, 0.7, c), 5, 15));
  EXPECT_FALSE(in_view_range(r, c, id, view(40, 70, -47, 0.7, c), 5, 15));
  EXPECT_FALSE(in_view_range(r, c, id, view(40, 70, -43, 0.7, c), 5, 5));
}

TEST(ViewRange, AnObjectSeenOffTheAxisKeepsItsInPlaneTurn) {
  // Seen steeply from above and 25 deg off the optical axis, the object's z axis leans in the
  // image far from its on-axis direction; the test turns the camera back first.
  const Eigen::Vector3d c = Eigen::Vector3d::Zero();
  const std::vector<geometry::SE3> id{geometry::SE3()};
  const ViewRange r = range();
  for (const double off : {-25.0, 0.0, 25.0}) {
    EXPECT_TRUE(in_view_range(r, c, id, view(65, 10, 25, 0.7, c, off), 0.5, 0.5)) << off;
    EXPECT_FALSE(in_view_range(r, c, id, view(65, 10, 33, 0.7, c, off), 0.5, 0.5)) << off;
  }
}

TEST(ViewRange, ASymmetricEquivalentInRangeSuffices) {
  // Seen from 40 deg below, a pose is out of range. Under a half turn about the object's x axis
  // (a symmetry of a box) it is seen from 40 deg above, but upside down in the image: in range
  // only when the in-plane turn is not limited.
  const Eigen::Vector3d c = Eigen::Vector3d::Zero();
  const ViewRange r = range();
  const geometry::SE3 T = view(-40, 70, 0, 0.7, c);  // from below
  const std::vector<geometry::SE3> id{geometry::SE3()};
  EXPECT_FALSE(in_view_range(r, c, id, T, 5, 180));
  const geometry::SE3 Rx = geometry::SE3::from_rvec(Eigen::Vector3d::Zero(), Eigen::Vector3d(3.14159265358979323846, 0, 0));
  const std::vector<geometry::SE3> sym{geometry::SE3(), Rx};
  EXPECT_FALSE(in_view_range(r, c, sym, T, 5, 15));
  EXPECT_TRUE(in_view_range(r, c, sym, T, 5, 180));
}
