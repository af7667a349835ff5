// v4r - robust model-based object tracking. MIT licence.

#include "v4r/io/pose_io.hpp"

#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace v4r::io {
namespace {

using test::TempDir;
using test::write_file;

std::string read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Random pose: translation in [-2, 2] m, rotation angle up to 3 rad about a random axis.
geometry::SE3 random_pose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d t(2.0 * u(rng), 2.0 * u(rng), 2.0 * u(rng) + 3.0);
  Eigen::Vector3d axis(u(rng), u(rng), u(rng));
  axis.normalize();
  const double angle = 1.5 * (u(rng) + 1.0);
  return geometry::SE3::from_rvec(t, axis * angle);
}

TEST(PoseIo, ParsesSixNumbers) {
  const Expected<geometry::SE3> T = parse_pose("0.1 -0.2 1.5 0.01 0.2 -0.3", "<string>");
  ASSERT_TRUE(T) << T.error().to_string();
  EXPECT_EQ(T->translation(), Eigen::Vector3d(0.1, -0.2, 1.5));
  const Eigen::Vector3d r = T->rvec();
  EXPECT_NEAR(r.x(), 0.01, 1e-15);
  EXPECT_NEAR(r.y(), 0.2, 1e-15);
  EXPECT_NEAR(r.z(), -0.3, 1e-15);
  // Rotation matches Rodrigues: R * axis = axis, angle = |r|.
  const Eigen::Vector3d w(0.01, 0.2, -0.3);
  EXPECT_LT((T->rotation() * w - w).norm(), 1e-15);
  EXPECT_NEAR(Eigen::AngleAxisd(T->rotation()).angle(), w.norm(), 1e-15);
}

TEST(PoseIo, AcceptsCommasCommentsLinesAndCrlf) {
  const Expected<geometry::SE3> T =
      parse_pose("# T_cam_obj\r\n0.1, -0.2,\t1.5,   # metres\r\n\r\n+0.01,0.2 , -3e-1\r\n# end\r\n", "<string>");
  ASSERT_TRUE(T) << T.error().to_string();
  EXPECT_EQ(T->translation(), Eigen::Vector3d(0.1, -0.2, 1.5));
  EXPECT_LT((T->rvec() - Eigen::Vector3d(0.01, 0.2, -0.3)).norm(), 1e-15);
}

/// A malformed pose: where (line, column), which field and what.
struct BadPose {
  const char* name;
  const char* text;
  int line;
  int column;
  const char* field;
  const char* fragment;
};

class PoseIoMalformed : public ::testing::TestWithParam<BadPose> {};

TEST_P(PoseIoMalformed, ReportsLineColumnAndWhat) {
  const BadPose& b = GetParam();
  const Expected<geometry::SE3> T = parse_pose(b.text, "pose.txt");
  ASSERT_FALSE(T) << b.name;
  const Error& e = T.error();
  EXPECT_EQ(e.file, "pose.txt");
  EXPECT_EQ(e.line, b.line) << e.to_string();
  EXPECT_EQ(e.column, b.column) << e.to_string();
  EXPECT_EQ(e.field, b.field) << e.to_string();
  EXPECT_NE(e.message.find(b.fragment), std::string::npos) << e.to_string();
}

INSTANTIATE_TEST_SUITE_P(
    Table, PoseIoMalformed,
    ::testing::Values(BadPose{"five_numbers", "0.1 0.2 0.3 0.4 0.5\n", 1, 20, "rz", "got 5"},
                      BadPose{"five_over_lines", "# pose\n0.1 0.2 0.3\n0.4 0.5  # no rz\n\n", 3, 8, "rz", "got 5"},
                      BadPose{"seven_numbers", "0.1 0.2 0.3 0.4 0.5 0.6 0.7\n", 1, 25, "", "found a seventh: '0.7'"},
                      BadPose{"seven_with_commas", "0.1,0.2,0.3,\n0.4,0.5,0.6,7\n", 2, 13, "", "seventh"},
                      BadPose{"abc", "abc\n", 1, 1, "tx", "expected a number, got 'abc'"},
                      BadPose{"abc_in_middle", "0.1 0.2\n  0.3 abc 0.5 0.6\n", 2, 7, "rx",
                              "expected a number, got 'abc'"},
                      BadPose{"trailing_garbage", "0.1 0.2 0.3 0.4 0.5 0.6x\n", 1, 21, "rz", "got '0.6x'"},
                      BadPose{"nan", "0.1 0.2 nan 0.4 0.5 0.6\n", 1, 9, "tz", "not a finite number: 'nan'"},
                      BadPose{"inf", "0.1 0.2 0.3 0.4 -inf 0.6\n", 1, 17, "ry", "not a finite number"},
                      BadPose{"overflow", "1e400 0.2 0.3 0.4 0.5 0.6\n", 1, 1, "tx", "not a finite number"},
                      BadPose{"empty", "", 1, 1, "tx", "got 0"},
                      BadPose{"only_comment", "# nothing\n", 1, 1, "tx", "got 0"}),
    [](const ::testing::TestParamInfo<BadPose>& info) { return std::string(info.param.name); });

TEST(PoseIo, PoseFileRoundTrip) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  std::mt19937 rng(7);
  for (int i = 0; i < 50; ++i) {
    const geometry::SE3 T = random_pose(rng);
    const std::string path = dir.file("pose_" + std::to_string(i) + ".txt");
    const Expected<void> saved = save_pose_file(path, T);
    ASSERT_TRUE(saved) << saved.error().to_string();
    const Expected<geometry::SE3> back = load_pose_file(path);
    ASSERT_TRUE(back) << back.error().to_string();
    EXPECT_EQ(back->translation(), T.translation());  // 17 significant digits: exact
    EXPECT_LT(geometry::rotation_angle_between(*back, T), 1e-13);
  }
}

TEST(PoseIo, SavedPoseFileIsSixNumbersAfterAComment) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("pose.txt");
  ASSERT_TRUE(
      save_pose_file(path, geometry::SE3::from_rvec(Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(0, 0, 0.5))));
  std::istringstream in(read_file(path));
  std::string comment, line;
  std::getline(in, comment);
  std::getline(in, line);
  EXPECT_EQ(comment.rfind('#', 0), 0u);
  std::istringstream nums(line);
  std::vector<double> v;
  double x = 0;
  while (nums >> x) v.push_back(x);
  ASSERT_EQ(v.size(), 6u);
  EXPECT_EQ(v[0], 0.1);
  EXPECT_EQ(v[2], 0.3);
  EXPECT_NEAR(v[5], 0.5, 1e-16);
}

TEST(PoseIo, LoadPoseFileErrorsNameThePath) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string missing = dir.file("missing.txt");
  Expected<geometry::SE3> T = load_pose_file(missing);
  ASSERT_FALSE(T);
  EXPECT_EQ(T.error().file, missing);
  EXPECT_NE(T.error().message.find(missing), std::string::npos);

  const std::string bad = dir.file("bad.txt");
  write_file(bad, "0 0 1\r\n0 0 x\r\n");
  T = load_pose_file(bad);
  ASSERT_FALSE(T);
  EXPECT_EQ(T.error().to_string(), bad + ":2:5: rz: expected a number, got 'x'");
}

TEST(PoseIo, CsvRoundTrip) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  std::mt19937 rng(11);
  std::vector<PoseRow> rows;
  for (int i = 0; i < 40; ++i) rows.push_back(PoseRow{3 * i + 1, random_pose(rng)});
  const std::string path = dir.file("gt.csv");
  const Expected<void> saved = save_pose_csv(path, rows);
  ASSERT_TRUE(saved) << saved.error().to_string();
  EXPECT_EQ(read_file(path).substr(0, 27), "frame,tx,ty,tz,qw,qx,qy,qz\n");
  const Expected<std::vector<PoseRow>> back = load_pose_csv(path);
  ASSERT_TRUE(back) << back.error().to_string();
  ASSERT_EQ(back->size(), rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ((*back)[i].frame, rows[i].frame);
    EXPECT_EQ((*back)[i].T_cam_obj.translation(), rows[i].T_cam_obj.translation());
    // Written with qw >= 0: the same rotation, exactly, up to the quaternion's sign.
    EXPECT_LT(((*back)[i].T_cam_obj.quaternion().coeffs() - canonical(rows[i].T_cam_obj.quaternion()).coeffs()).norm(),
              1e-15);
    EXPECT_GE((*back)[i].T_cam_obj.quaternion().w(), 0.0);
  }
}

TEST(PoseIo, CsvColumnsFoundByNameExtraIgnored) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("shuffled.csv");
  // qw first among the quaternion entries, columns out of order, extra columns, CRLF, comments.
  write_file(path,
             "# exported\r\n"
             "time, frame, qw, qx, qy, qz, tz, ty, tx, score\r\n"
             "0.033, 5, 1, 0, 0, 0, 1.5, -0.25, 0.125, 0.9\r\n"
             "\r\n"
             "0.066, 6, 0.70710678118654752, 0, 0.70710678118654752, 0, 2.0, 0.0, -1.0, 0.8\r\n");
  const Expected<std::vector<PoseRow>> rows = load_pose_csv(path);
  ASSERT_TRUE(rows) << rows.error().to_string();
  ASSERT_EQ(rows->size(), 2u);
  EXPECT_EQ((*rows)[0].frame, 5);
  EXPECT_EQ((*rows)[0].T_cam_obj.translation(), Eigen::Vector3d(0.125, -0.25, 1.5));
  EXPECT_LT(geometry::rotation_angle_between((*rows)[0].T_cam_obj, geometry::SE3()), 1e-15);
  EXPECT_EQ((*rows)[1].frame, 6);
  EXPECT_EQ((*rows)[1].T_cam_obj.translation(), Eigen::Vector3d(-1.0, 0.0, 2.0));
  // 90 degrees about y: x axis goes to -z.
  EXPECT_LT(((*rows)[1].T_cam_obj.rotation() * Eigen::Vector3d::UnitX() - Eigen::Vector3d(0, 0, -1)).norm(), 1e-15);
}

TEST(PoseIo, CsvHeaderOnlyIsEmpty) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file("empty_rows.csv");
  write_file(path, "frame,tx,ty,tz,qw,qx,qy,qz\n");
  const Expected<std::vector<PoseRow>> rows = load_pose_csv(path);
  ASSERT_TRUE(rows) << rows.error().to_string();
  EXPECT_TRUE(rows->empty());
}

/// A malformed CSV: where (line, column), which column name and what.
struct BadCsv {
  const char* name;
  const char* text;
  int line;
  int column;  ///< 0: not checked
  const char* field;
  const char* fragment;
};

class PoseCsvMalformed : public ::testing::TestWithParam<BadCsv> {};

TEST_P(PoseCsvMalformed, ReportsLineAndColumnName) {
  const BadCsv& b = GetParam();
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string path = dir.file(std::string(b.name) + ".csv");
  write_file(path, b.text);
  const Expected<std::vector<PoseRow>> rows = load_pose_csv(path);
  ASSERT_FALSE(rows) << b.name;
  const Error& e = rows.error();
  EXPECT_EQ(e.file, path);
  EXPECT_EQ(e.line, b.line) << e.to_string();
  if (b.column != 0) {
    EXPECT_EQ(e.column, b.column) << e.to_string();
  }
  EXPECT_EQ(e.field, b.field) << e.to_string();
  EXPECT_NE(e.message.find(b.fragment), std::string::npos) << e.to_string();
}

INSTANTIATE_TEST_SUITE_P(
    Table, PoseCsvMalformed,
    ::testing::Values(
        BadCsv{"empty", "", 1, 1, "", "missing header"},
        BadCsv{"no_header", "1,0,0,1,1,0,0,0\n", 1, 0, "frame", "no column 'frame'"},
        BadCsv{"missing_qz", "frame,tx,ty,tz,qw,qx,qy\n0,0,0,1,1,0,0\n", 1, 0, "qz", "no column 'qz'"},
        BadCsv{"duplicate_tx", "frame,tx,ty,tz,qw,qx,qy,qz,tx\n", 1, 28, "tx", "appears twice"},
        BadCsv{"text_in_tx", "frame,tx,ty,tz,qw,qx,qy,qz\n0,0,0,1,1,0,0,0\n1,oops,0,1,1,0,0,0\n", 3, 3, "tx",
               "expected a number, got 'oops'"},
        BadCsv{"nan_in_qy", "frame,tx,ty,tz,qw,qx,qy,qz\r\n0,0,0,1,1,0,NaN,0\r\n", 2, 13, "qy", "not a finite number"},
        BadCsv{"empty_field", "frame,tx,ty,tz,qw,qx,qy,qz\n0,0,,1,1,0,0,0\n", 2, 5, "ty", "got ''"},
        BadCsv{"short_row", "frame,tx,ty,tz,qw,qx,qy,qz\n0,0,0,1,1,0\n", 2, 0, "qy", "row has 6 fields"},
        BadCsv{"fractional_frame", "frame,tx,ty,tz,qw,qx,qy,qz\n2.5,0,0,1,1,0,0,0\n", 2, 1, "frame", "integer"},
        BadCsv{"non_unit_quaternion", "frame,tx,ty,tz,qw,qx,qy,qz\n0,0,0,1,1,1,0,0\n", 2, 9, "qw", "not unit"}),
    [](const ::testing::TestParamInfo<BadCsv>& info) { return std::string(info.param.name); });

TEST(PoseIo, LoadCsvMissingFileNamesThePath) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string missing = dir.file("none.csv");
  const Expected<std::vector<PoseRow>> rows = load_pose_csv(missing);
  ASSERT_FALSE(rows);
  EXPECT_NE(rows.error().message.find(missing), std::string::npos);
}

}  // namespace
}  // namespace v4r::io
