// v4r - robust model-based object tracking. MIT licence.
// Events, replies and the greeting: exact text, exact round trips, and rejected lines.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>

#include "v4r/protocol/protocol.hpp"

namespace vp = v4r::protocol;

namespace {

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

template <std::size_t N>
bool same_bits(const std::array<double, N>& a, const std::array<double, N>& b) {
  for (std::size_t i = 0; i < N; ++i)
    if (!same_bits(a[i], b[i])) return false;
  return true;
}

vp::ObjectPoseEvent simple_pose() {
  vp::ObjectPoseEvent e;
  e.object = "box";
  e.frame = 17;
  e.stamp = 0.5666666666666667;
  e.t = {0.01, -0.02, 0.5};
  e.q = {1, 0, 0, 0};
  for (int i = 0; i < 6; ++i) e.cov[i * 6 + i] = i < 3 ? 1e-6 : 1e-4;
  e.quality = 0.93;
  e.status = vp::TrackStatus::kTracking;
  return e;
}

// The parsed value (by value: the argument is often a temporary), or a test failure.
template <class T>
T get_ok(const std::variant<T, vp::ParseError>& r) {
  if (const auto* e = std::get_if<vp::ParseError>(&r)) {
    ADD_FAILURE() << e->code << ": " << e->message;
    return T{};
  }
  return std::get<T>(r);
}

}  // namespace

TEST(ProtocolEvents, ObjectPoseExactText) {
  const std::string line = vp::format(simple_pose());
  EXPECT_EQ(line,
            "ObjectPose object=box frame=17 stamp=0.5666666666666667 t=0.01,-0.02,0.5 q=1,0,0,0 "
            "cov=1e-06,0,0,0,0,0,0,1e-06,0,0,0,0,0,0,1e-06,0,0,0,0,0,0,1e-04,0,0,0,0,0,0,1e-04,0,0,0,0,0,0,1e-04 "
            "quality=0.93 status=tracking");
  EXPECT_EQ(get_ok(vp::parse_object_pose(line)), simple_pose());
  EXPECT_EQ(get_ok(vp::parse_object_pose(line + "\r")), simple_pose());
}

TEST(ProtocolEvents, ObjectPoseRoundTripIsBitExact) {
  std::mt19937_64 rng(20240405);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::uniform_int_distribution<int> expo(-320, 300);
  const double specials[] = {0.0, -0.0, 5e-324, -2.2250738585072014e-308, 1.7976931348623157e308, 1.0 / 3.0, 0.1};
  const vp::TrackStatus statuses[] = {vp::TrackStatus::kTracking, vp::TrackStatus::kDegraded, vp::TrackStatus::kLost,
                                      vp::TrackStatus::kFailed};
  for (int n = 0; n < 2000; ++n) {
    vp::ObjectPoseEvent e;
    e.object = "obj_" + std::to_string(n);
    e.frame = static_cast<std::uint64_t>(n) * 1000003u + (n == 0 ? std::numeric_limits<std::uint64_t>::max() : 0u);
    e.stamp = n / 30.0;
    for (double& v : e.t) v = uni(rng);
    double norm = 0.0;
    for (double& v : e.q) {
      v = uni(rng);
      norm += v * v;
    }
    for (double& v : e.q) v /= std::sqrt(norm);
    for (std::size_t i = 0; i < e.cov.size(); ++i)
      e.cov[i] = (i % 7 == 0) ? specials[(n + i) % 7] : uni(rng) * std::pow(10.0, expo(rng));
    e.quality = (n % 11) / 10.0;
    e.status = statuses[n % 4];
    const std::string line = vp::format(e);
    const auto back = get_ok(vp::parse_object_pose(line));
    ASSERT_EQ(back.object, e.object);
    ASSERT_EQ(back.frame, e.frame);
    ASSERT_TRUE(same_bits(back.stamp, e.stamp)) << line;
    ASSERT_TRUE(same_bits(back.t, e.t)) << line;
    ASSERT_TRUE(same_bits(back.q, e.q)) << line;
    ASSERT_TRUE(same_bits(back.cov, e.cov)) << line;
    ASSERT_TRUE(same_bits(back.quality, e.quality));
    ASSERT_EQ(back.status, e.status);
    ASSERT_EQ(vp::format(back), line);  // canonical
    ASSERT_LT(line.size(), 1400u);      // 36 numbers of at most 24 characters each, and the rest
  }
}

TEST(ProtocolEvents, SystemStatusExactTextAndRoundTrip) {
  vp::SystemStatusEvent s{41, 12.375, 120, 97, 11, 3};
  const std::string line = vp::format(s);
  EXPECT_EQ(line, "SystemStatus frame=41 cycle_ms=12.375 features_found=120 features_used=97 outliers=11 overruns=3");
  EXPECT_EQ(get_ok(vp::parse_system_status(line)), s);
  s.failed = 2;  // objects whose cycle failed: a trailing key, sent only when there are any
  EXPECT_EQ(vp::format(s), line + " failed=2");
  EXPECT_EQ(get_ok(vp::parse_system_status(vp::format(s))), s);
  s.failed = 0;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ms(0.0, 100.0);
  for (int n = 0; n < 500; ++n) {
    vp::SystemStatusEvent e{static_cast<std::uint64_t>(n), ms(rng), rng() % 1000u, rng() % 500u, rng() % 50u, rng(),
                            n % 5 == 0 ? rng() % 3u : 0u};
    const auto back = get_ok(vp::parse_system_status(vp::format(e)));
    ASSERT_EQ(back, e);
    ASSERT_TRUE(same_bits(back.cycle_ms, e.cycle_ms));
  }
}

TEST(ProtocolEvents, SceneFieldsRefAndCamerasAreSentOnlyWhenSetAndRoundTrip) {
  // `v4r serve --scene`: the pose's reference frame and the per-camera status are trailing keys.
  vp::ObjectPoseEvent p = simple_pose();
  const std::string plain = vp::format(p);
  EXPECT_EQ(plain.find(" ref="), std::string::npos);
  p.ref = "left";
  EXPECT_EQ(vp::format(p), plain + " ref=left");
  EXPECT_EQ(get_ok(vp::parse_object_pose(vp::format(p))), p);

  vp::SystemStatusEvent s{41, 12.375, 120, 97, 11, 3};
  const std::string line = vp::format(s);
  s.cameras = {{"left", 42, true}, {"right", 41, false}};
  EXPECT_EQ(vp::format(s), line + " cameras=left:42:1,right:41:0");
  EXPECT_EQ(get_ok(vp::parse_system_status(vp::format(s))), s);
  for (const char* bad : {"left", "left:1", "left:x:1", "left:1:2", ":1:1", "left:1:1,", "left:-1:1"}) {
    const auto r = vp::parse_system_status(line + " cameras=" + bad);
    EXPECT_TRUE(std::holds_alternative<vp::ParseError>(r)) << bad;
  }
}

TEST(ProtocolEvents, UnknownKeysAreIgnoredForNewerServers) {
  const std::string line = vp::format(simple_pose()) + " latency_ms=3.2 note=\"new field\"";
  EXPECT_EQ(get_ok(vp::parse_object_pose(line)), simple_pose());
  EXPECT_EQ(get_ok(vp::parse_system_status(
                "SystemStatus objects=2 frame=1 cycle_ms=2 features_found=3 features_used=2 outliers=1 overruns=0")),
            (vp::SystemStatusEvent{1, 2.0, 3, 2, 1, 0}));
}

TEST(ProtocolEvents, RejectedEventLines) {
  const std::string good = vp::format(simple_pose());
  auto replace = [&](const std::string& from, const std::string& to) {
    std::string s = good;
    s.replace(s.find(from), from.size(), to);
    return s;
  };
  struct Row {
    std::string line, code, fragment;
  };
  const Row rows[] = {
      {replace("status=tracking", "status=confused"), "bad_argument", "tracking|degraded|lost"},
      {replace("q=1,0,0,0", "q=1,0,0"), "bad_vector", "q=: expected 4 comma-separated numbers qw,qx,qy,qz, got 3"},
      {replace("cov=1e-06,", "cov="), "bad_vector", "expected 36 comma-separated numbers (6x6 row-major), got 35"},
      {replace("cov=1e-06,", "cov=nan,"), "not_finite", "cov=: component 1 'nan'"},
      {replace(" quality=0.93", ""), "missing_argument", "missing argument quality="},
      {replace("frame=17", "frame=-17"), "bad_number", "'-17' is not a whole number"},
      {replace("frame=17", "frame=17 frame=18"), "duplicate_argument", "frame= given twice"},
      {replace("object=box", "object=\"a box\""), "bad_name", "'a box'"},
      {"SystemStatus frame=1", "missing_argument", "missing argument cycle_ms="},
  };
  for (const Row& row : rows) {
    SCOPED_TRACE(row.line);
    const vp::ParseError* e = nullptr;
    const auto pose = vp::parse_object_pose(row.line);
    const auto status = vp::parse_system_status(row.line);
    e = row.line.rfind("ObjectPose", 0) == 0 ? std::get_if<vp::ParseError>(&pose) : std::get_if<vp::ParseError>(&status);
    ASSERT_NE(e, nullptr);
    EXPECT_EQ(e->code, row.code) << e->message;
    EXPECT_NE(e->message.find(row.fragment), std::string::npos) << e->message;
  }
  const auto wrong = vp::parse_object_pose("SystemStatus frame=1");
  ASSERT_TRUE(std::holds_alternative<vp::ParseError>(wrong));
  EXPECT_EQ(std::get<vp::ParseError>(wrong).code, "unknown_command");
}

TEST(ProtocolReplies, OkErrAndHelloText) {
  EXPECT_EQ(vp::hello(), "Hello version=1");
  EXPECT_EQ(vp::hello(true), "Hello version=1 auth=required");
  EXPECT_EQ(vp::format_ok("Ping"), "OK Ping");
  EXPECT_EQ(vp::format_ok("GetParam", "name=track.rows value=24"), "OK GetParam name=track.rows value=24");
  EXPECT_EQ(vp::format_err("AddObject", "exists", R"(object "box" exists \ already)"),
            R"(ERR AddObject code=exists msg="object \"box\" exists \\ already")");
  EXPECT_EQ(vp::format_err("Bad\nName", "x", "m"), R"(ERR ? code=x msg="m")");
  EXPECT_EQ(vp::format_err("Ping", "not a code", "m"), R"(ERR Ping code=internal msg="m")");
  EXPECT_EQ(vp::format_err("Ping", "bad_byte", "tab\there"), R"(ERR Ping code=bad_byte msg="tab?here")");
}

TEST(ProtocolReplies, ServerLinesParse) {
  auto parse_ok = [](const std::string& line) {
    const auto r = vp::parse_server_line(line);
    if (const auto* e = std::get_if<vp::ParseError>(&r)) ADD_FAILURE() << line << ": " << e->message;
    return std::get<vp::ServerMessage>(r);
  };
  EXPECT_EQ(std::get<vp::HelloMessage>(parse_ok("Hello version=1")), (vp::HelloMessage{1, false}));
  EXPECT_EQ(std::get<vp::HelloMessage>(parse_ok("Hello version=1 auth=required\r")), (vp::HelloMessage{1, true}));

  const auto ok = std::get<vp::Reply>(parse_ok(R"(OK GetParam name=track.rows value=24 doc="rows per window")"));
  EXPECT_TRUE(ok.ok);
  EXPECT_EQ(ok.command, "GetParam");
  ASSERT_NE(ok.find("value"), nullptr);
  EXPECT_EQ(*ok.find("value"), "24");
  EXPECT_EQ(*ok.find("doc"), "rows per window");
  EXPECT_EQ(ok.find("unit"), nullptr);

  // Replies as the server writes them: a state word, dotted parameter names as keys.
  const auto display = std::get<vp::Reply>(parse_ok("OK Display on"));
  EXPECT_EQ(display.words, std::vector<std::string>{"on"});
  const auto list = std::get<vp::Reply>(parse_ok("OK ListParams count=2 track.rows=24 edge.mode=\"a b\""));
  ASSERT_NE(list.find("track.rows"), nullptr);
  EXPECT_EQ(*list.find("track.rows"), "24");
  EXPECT_EQ(*list.find("edge.mode"), "a b");

  const std::string msg = R"(a "quoted" \ message)";
  const auto err = std::get<vp::Reply>(parse_ok(vp::format_err("RemoveObject", "unknown_object", msg)));
  EXPECT_FALSE(err.ok);
  EXPECT_EQ(err.command, "RemoveObject");
  EXPECT_EQ(err.code, "unknown_object");
  EXPECT_EQ(err.message, msg);

  EXPECT_EQ(std::get<vp::ObjectPoseEvent>(parse_ok(vp::format(simple_pose()))), simple_pose());
  const vp::SystemStatusEvent s{1, 2.5, 3, 2, 1, 0};
  EXPECT_EQ(std::get<vp::SystemStatusEvent>(parse_ok(vp::format(s))), s);

  for (const char* bad : {"", "OK", "OK x=1", "ERR Ping code=x", "ERR Ping msg=\"m\"", "Welcome", "OK Ping x=\"open",
                          "OK Ping a=1 a=2", "Hello", "Hello version=x"}) {
    SCOPED_TRACE(bad);
    EXPECT_TRUE(std::holds_alternative<vp::ParseError>(vp::parse_server_line(bad)));
  }
}

TEST(ProtocolReplies, EveryParseErrorBecomesAValidErrLine) {
  // Whatever the client sent, the ERR reply built from the ParseError is itself a valid line
  // that a client reads back with the same code and message.
  const std::string inputs[] = {"", "Bogus", "AddObject name=\"x", std::string("\x01\x02\xff", 3),
                                "AddObject name=b\"o", "a=b", std::string(5000, 'A'), "Display maybe"};
  for (const std::string& in : inputs) {
    const auto r = vp::parse(in);
    ASSERT_TRUE(std::holds_alternative<vp::ParseError>(r));
    const auto& e = std::get<vp::ParseError>(r);
    const auto back = vp::parse_server_line(vp::format_err(e));
    ASSERT_TRUE(std::holds_alternative<vp::ServerMessage>(back)) << vp::format_err(e);
    const auto& reply = std::get<vp::Reply>(std::get<vp::ServerMessage>(back));
    EXPECT_EQ(reply.code, e.code);
    EXPECT_EQ(reply.message, e.message);
    EXPECT_EQ(reply.command, e.command);
  }
}

TEST(ProtocolEvents, SearchingObjectPoseHasNoPose) {
  vp::ObjectPoseEvent e;
  e.object = "box";
  e.frame = 7;
  e.stamp = 0.25;
  e.quality = 0.0;
  e.status = vp::TrackStatus::kSearching;
  const std::string line = vp::format(e);
  EXPECT_EQ(line, "ObjectPose object=box frame=7 stamp=0.25 quality=0 status=searching");
  const auto back = vp::parse_object_pose(line);
  ASSERT_TRUE(std::holds_alternative<vp::ObjectPoseEvent>(back));
  EXPECT_EQ(std::get<vp::ObjectPoseEvent>(back), e);
  // Any other status still needs its pose.
  const auto bad = vp::parse_object_pose("ObjectPose object=box frame=7 stamp=0.25 quality=0 status=lost");
  EXPECT_TRUE(std::holds_alternative<vp::ParseError>(bad));
}
