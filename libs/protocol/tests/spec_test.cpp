// v4r - robust model-based object tracking. MIT licence.
// docs/protocol.md is the specification: its examples are checked against the code, so that the
// document cannot drift from the parser.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "v4r/protocol/protocol.hpp"

namespace vp = v4r::protocol;

namespace {

// The source tree, from CMake (__FILE__ is relative to the build folder when ccache's
// CCACHE_BASEDIR rewrites the paths, and ctest runs elsewhere).
std::string read_spec() {
  std::ifstream in(std::string(V4R_SOURCE_DIR) + "/docs/protocol.md");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Markdown table cells escape '|' as "\|"; the examples write a tab as <TAB>.
std::string unescape(const std::string& s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s.compare(i, 2, "\\|") == 0) {
      out += '|';
      i += 1;
    } else if (s.compare(i, 5, "<TAB>") == 0) {
      out += '\t';
      i += 4;
    } else {
      out += s[i];
    }
  }
  return out;
}

}  // namespace

TEST(ProtocolSpec, ErrorExamplesMatchTheParser) {
  const std::string spec = read_spec();
  ASSERT_FALSE(spec.empty()) << V4R_SOURCE_DIR "/docs/protocol.md not found";
  // Rows like: | code | when | `line` → `ERR ...` |
  const std::string arrow = "` → `";
  int checked = 0;
  std::istringstream lines(spec);
  for (std::string row; std::getline(lines, row);) {
    const std::size_t a = row.find(arrow);
    if (a == std::string::npos || row.rfind("| `", 0) != 0) continue;
    const std::size_t start = row.rfind(" `", a);
    const std::size_t end = row.find("` |", a + arrow.size());
    ASSERT_NE(start, std::string::npos) << row;
    ASSERT_NE(end, std::string::npos) << row;
    const std::string input = unescape(row.substr(start + 2, a - start - 2));
    const std::string reply = unescape(row.substr(a + arrow.size(), end - a - arrow.size()));
    SCOPED_TRACE(input);
    const auto r = vp::parse(input);
    ASSERT_TRUE(std::holds_alternative<vp::ParseError>(r)) << input;
    EXPECT_EQ(vp::format_err(std::get<vp::ParseError>(r)), reply);
    ++checked;
  }
  EXPECT_GE(checked, 13);
}

TEST(ProtocolSpec, EveryErrorCodeIsDocumented) {
  const std::string spec = read_spec();
  ASSERT_FALSE(spec.empty()) << V4R_SOURCE_DIR "/docs/protocol.md not found";
  namespace c = vp::code;
  for (std::string_view code :
       {c::kEmptyLine, c::kTooLong, c::kBadByte, c::kBadSyntax, c::kUnknownCommand, c::kUnknownArgument,
        c::kDuplicateArgument, c::kMissingArgument, c::kBadArgument, c::kBadName, c::kBadNumber, c::kNotFinite,
        c::kBadVector, c::kOutOfRange, c::kTooLarge, c::kUnauthorized, c::kUnknownObject, c::kExists,
        c::kUnknownFeature, c::kUnknownParam, c::kBadValue, c::kBadModel, c::kUnsupported, c::kIoError, c::kTruncated,
        c::kBusy, c::kInternal}) {
    EXPECT_NE(spec.find("| `" + std::string(code) + "` |"), std::string::npos) << code;
  }
}

TEST(ProtocolSpec, EventAndCommandExamplesParse) {
  const std::string spec = read_spec();
  ASSERT_FALSE(spec.empty()) << V4R_SOURCE_DIR "/docs/protocol.md not found";
  int commands = 0, events = 0, scene_events = 0;
  std::istringstream lines(spec);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("C: ", 0) == 0) {
      const std::string cmd = line.substr(3);
      // Payload lines of the inline model example are model text, not commands.
      if (cmd.empty() || (cmd[0] >= '0' && cmd[0] <= '9') || cmd == "V1") continue;
      const auto r = vp::parse(cmd);
      EXPECT_TRUE(std::holds_alternative<vp::Command>(r)) << cmd;
      ++commands;
    } else if (line.rfind("ObjectPose object=box frame=17", 0) == 0) {
      EXPECT_TRUE(std::holds_alternative<vp::ObjectPoseEvent>(vp::parse_object_pose(line))) << line;
      ++events;
    } else if (line.rfind("SystemStatus frame=41", 0) == 0) {
      EXPECT_TRUE(std::holds_alternative<vp::SystemStatusEvent>(vp::parse_system_status(line))) << line;
      ++events;
    } else if (line.rfind("S: SystemStatus ", 0) == 0) {  // the example of `serve --scene`
      const auto r = vp::parse_system_status(line.substr(3));
      EXPECT_TRUE(std::holds_alternative<vp::SystemStatusEvent>(r)) << line;
      if (const auto* e = std::get_if<vp::SystemStatusEvent>(&r)) {
        EXPECT_EQ(e->cameras.size(), 2u) << line;
      }
      ++scene_events;
    } else if (line.rfind("S: OK ", 0) == 0 || line.rfind("S: Hello", 0) == 0) {
      EXPECT_TRUE(std::holds_alternative<vp::ServerMessage>(vp::parse_server_line(line.substr(3)))) << line;
    }
  }
  EXPECT_GE(commands, 12);
  EXPECT_EQ(events, 2);
  EXPECT_EQ(scene_events, 1);
}

TEST(ProtocolSpec, InlineModelExampleHasTheStatedLength) {
  const std::string spec = read_spec();
  ASSERT_FALSE(spec.empty()) << V4R_SOURCE_DIR "/docs/protocol.md not found";
  const std::string head = "C: AddModel object=box format=cao bytes=";
  const std::size_t at = spec.find(head);
  ASSERT_NE(at, std::string::npos);
  const std::size_t bytes = std::stoul(spec.substr(at + head.size()));
  std::istringstream lines(spec.substr(spec.find('\n', at) + 1));
  std::string payload;
  for (std::string line; std::getline(lines, line) && line.rfind("C: ", 0) == 0;) payload += line.substr(3) + "\n";
  EXPECT_EQ(payload.size(), bytes);
}
