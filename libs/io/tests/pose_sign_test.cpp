// v4r - robust model-based object tracking. MIT licence.
// Quaternion sign in written CSVs (qw >= 0) and the pose numbers as given.

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "v4r/io/pose_io.hpp"

namespace v4r::io {
namespace {

namespace fs = std::filesystem;

TEST(PoseSign, CanonicalKeepsTheRotationAndMakesQwNonNegative) {
  const Eigen::Quaterniond q(-0.5, 0.5, -0.5, 0.5);
  const Eigen::Quaterniond c = canonical(q);
  EXPECT_GE(c.w(), 0.0);
  EXPECT_TRUE(c.toRotationMatrix().isApprox(q.toRotationMatrix(), 1e-15));
  const Eigen::Quaterniond zero_w(0.0, -1.0, 0.0, 0.0);
  EXPECT_EQ(canonical(zero_w).x(), 1.0);
  const Eigen::Quaterniond positive(0.6, 0.8, 0.0, 0.0);
  EXPECT_EQ(canonical(positive).coeffs(), positive.coeffs());
}

TEST(PoseSign, SavedCsvHasQwNonNegativeOnEveryRow) {
  // A rotation about z through pi: the quaternion's w changes sign half way.
  std::vector<PoseRow> rows;
  for (int i = 0; i < 40; ++i) {
    const double angle = 0.2 * i;
    rows.push_back(PoseRow{i, geometry::SE3::from_rvec(Eigen::Vector3d(0, 0, 0.6), Eigen::Vector3d(0, 0, angle))});
  }
  const fs::path path = fs::temp_directory_path() / ("v4r_sign_" + std::to_string(::getpid()) + ".csv");
  ASSERT_TRUE(save_pose_csv(path.string(), rows));
  auto back = load_pose_csv(path.string());
  fs::remove(path);
  ASSERT_TRUE(back) << back.error().to_string();
  ASSERT_EQ(back->size(), rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    EXPECT_GE((*back)[i].T_cam_obj.quaternion().w(), 0.0) << "row " << i;
    EXPECT_TRUE((*back)[i].T_cam_obj.rotation().isApprox(rows[i].T_cam_obj.rotation(), 1e-12)) << "row " << i;
  }
}

TEST(PoseSign, NumbersAreKeptAsGiven) {
  auto v = parse_pose_numbers("0 0 0.6 120 63 -27", "--init-pose");
  ASSERT_TRUE(v) << v.error().to_string();
  EXPECT_EQ((*v)[3], 120.0);  // not wrapped into a rotation of less than pi
  EXPECT_EQ((*v)[5], -27.0);
  auto bad = parse_pose_numbers("0 0 0.6 1 2", "--init-pose");
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().field, "rz");
}

}  // namespace
}  // namespace v4r::io
