// v4r - robust model-based object tracking. MIT licence.
// Names and options of ROS 2 on the wire (what goes over the wire is checked by the Fast DDS
// reader in wire_test/).
#include <gtest/gtest.h>

#include "v4r/ros2/ros2_publisher.hpp"

using v4r::ros2::check_namespace;
using v4r::ros2::ros_name;

TEST(Ros2Names, Namespaces) {
  for (const char* ok : {"/", "/v4r", "/robot_1/v4r", "/a"}) EXPECT_TRUE(check_namespace(ok)) << ok;
  for (const char* bad : {"", "v4r", "/v4r/", "//v4r", "/v4r//x", "/1robot", "/v-4r", "/v4r x"}) {
    auto r = check_namespace(bad);
    ASSERT_FALSE(r) << bad;
    EXPECT_NE(r.error().to_string().find("--ros2-namespace"), std::string::npos) << r.error().to_string();
  }
}

TEST(Ros2Names, ObjectNamesBecomeRosNames) {
  EXPECT_EQ(ros_name("ship"), "ship");
  EXPECT_EQ(ros_name("ship-2.left"), "ship_2_left");
  EXPECT_EQ(ros_name("2nd"), "_2nd");
  EXPECT_EQ(ros_name(""), "_");
}

TEST(Ros2Publisher, RefusesBadOptions) {
  v4r::ros2::Ros2Options o;
  o.domain = 233;
  auto p = v4r::ros2::Ros2Publisher::create(o);
  ASSERT_FALSE(p);
  EXPECT_NE(p.error().to_string().find("233"), std::string::npos);
  o.domain = 0;
  o.ns = "v4r";
  EXPECT_FALSE(v4r::ros2::Ros2Publisher::create(o));
  o.ns = "/v4r";
  o.frame_id = "";
  EXPECT_FALSE(v4r::ros2::Ros2Publisher::create(o));
}
