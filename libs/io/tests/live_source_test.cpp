// v4r - robust model-based object tracking. MIT licence.
// Live sources hand out the newest frame and count the others as dropped. The camera is a
// GStreamer test pattern (skipped without GStreamer's base plugins unless V4R_REQUIRE_GSTREAMER=1).
#include <chrono>
#include <cstdlib>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "v4r/io/frame_source.hpp"

namespace {

bool require_gstreamer() {
  const char* v = std::getenv("V4R_REQUIRE_GSTREAMER");
  return v && std::string(v) == "1";
}

}  // namespace

TEST(LiveSource, LiveInputsAreRecognised) {
  EXPECT_TRUE(v4r::io::is_live_input("/dev/video0"));
  EXPECT_TRUE(v4r::io::is_live_input("gst:videotestsrc"));
  EXPECT_FALSE(v4r::io::is_live_input("frames/%06d.png"));
  EXPECT_FALSE(v4r::io::is_live_input("video.avi"));
}

TEST(LiveSource, MissingDeviceIsNamed) {
  auto s = v4r::io::FrameSource::open("/dev/video99");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().to_string().find("/dev/video99"), std::string::npos) << s.error().to_string();
  EXPECT_NE(s.error().to_string().find("does not exist"), std::string::npos) << s.error().to_string();
}

// A consumer slower than the camera gets the newest frames: every frame is either handed out or
// counted as dropped, some are dropped, and the frames handed out are in capture order.
TEST(LiveSource, SlowConsumerGetsNewestFrameAndCountsTheRest) {
  constexpr int kFrames = 40;
  auto s = v4r::io::FrameSource::open("gst:videotestsrc num-buffers=" + std::to_string(kFrames) +
                                      " ! video/x-raw,width=64,height=48,framerate=200/1 ! videoconvert"
                                      " ! appsink");
  if (!s) {
    if (require_gstreamer()) FAIL() << s.error().to_string();
    GTEST_SKIP() << "no GStreamer: " << s.error().to_string();
  }
  EXPECT_TRUE((*s)->live());
  EXPECT_EQ((*s)->size_hint(), -1);
  cv::Mat frame;
  int taken = 0;
  double last_capture = -1.0;
  for (;;) {
    auto more = (*s)->next(frame);
    ASSERT_TRUE(more) << more.error().to_string();
    if (!*more) break;
    ++taken;
    EXPECT_EQ(frame.cols, 64);
    EXPECT_EQ(frame.rows, 48);
    EXPECT_EQ(frame.type(), CV_8UC3);
    EXPECT_GT((*s)->capture_time_s(), last_capture);
    last_capture = (*s)->capture_time_s();
    std::this_thread::sleep_for(std::chrono::milliseconds(25));  // a tracker 5x slower than the 200 Hz camera
  }
  EXPECT_GT(taken, 0);
  EXPECT_GT((*s)->dropped(), 0);
  EXPECT_EQ(taken + (*s)->dropped(), kFrames);
}
