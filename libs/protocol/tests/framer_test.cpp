// v4r - robust model-based object tracking. MIT licence.
// Framer: lines, CRLF, over-long lines with bounded memory, AddModel payloads, any chunking.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "v4r/protocol/framer.hpp"

namespace vp = v4r::protocol;

namespace {

// A readable transcript of the frames: "L:<text>", "O:<command>", "P:<bytes>".
// Lines that parse as AddModel ... bytes=N make the transcript ask for the payload, as a server does.
std::vector<std::string> run(const std::string& stream, std::size_t chunk, std::size_t* max_buffered = nullptr) {
  vp::Framer f;
  std::vector<std::string> out;
  for (std::size_t i = 0; i < stream.size(); i += chunk) {
    f.feed(std::string_view(stream).substr(i, chunk));
    while (auto frame = f.next()) {
      if (auto* l = std::get_if<vp::Framer::Line>(&*frame)) {
        out.push_back("L:" + l->text);
        const auto r = vp::parse(l->text);
        if (const auto* c = std::get_if<vp::Command>(&r)) {
          if (vp::payload_bytes(*c) > 0) f.expect_payload(vp::payload_bytes(*c));
        } else if (std::get<vp::ParseError>(r).skip_bytes > 0) {
          f.expect_payload(std::get<vp::ParseError>(r).skip_bytes, false);
        }
      } else if (auto* o = std::get_if<vp::Framer::Overlong>(&*frame)) {
        out.push_back("O:" + o->error.command + ":" + o->error.code);
      } else {
        out.push_back("P:" + std::get<vp::Framer::Payload>(*frame).bytes);
      }
    }
    if (max_buffered != nullptr) *max_buffered = std::max(*max_buffered, f.buffered());
  }
  return out;
}

}  // namespace

TEST(ProtocolFramer, LinesWithLfAndCrlfInAnyChunking) {
  const std::string stream = "Ping\nAddObject name=a\r\n\r\n\nQuit\r\nPartial";
  const std::vector<std::string> expected = {"L:Ping", "L:AddObject name=a", "L:", "L:", "L:Quit"};
  for (std::size_t chunk : {1u, 2u, 3u, 7u, 1000u}) {
    SCOPED_TRACE(chunk);
    EXPECT_EQ(run(stream, chunk), expected);
  }
}

TEST(ProtocolFramer, OverlongLineIsReportedOnceAndMemoryStaysBounded) {
  const std::string stream = "Ping\nAddObject name=" + std::string(100000, 'x') + "\nPing\n";
  for (std::size_t chunk : {1u, 100u, 4096u, 65536u}) {
    SCOPED_TRACE(chunk);
    std::size_t max_buffered = 0;
    EXPECT_EQ(run(stream, chunk, &max_buffered),
              (std::vector<std::string>{"L:Ping", "O:AddObject:too_long", "L:Ping"}));
    EXPECT_LE(max_buffered, vp::kMaxLineBytes + 1);  // after next(), never more than one line
  }
}

TEST(ProtocolFramer, LimitIsExactAndExcludesCr) {
  const std::string body(vp::kMaxLineBytes, 'a');
  EXPECT_EQ(run(body + "\r\n", 1000), (std::vector<std::string>{"L:" + body}));
  EXPECT_EQ(run(body + "\n", 1), (std::vector<std::string>{"L:" + body}));
  EXPECT_EQ(run(body + "a\n", 1000), (std::vector<std::string>{"O:?:too_long"}));
  EXPECT_EQ(run(body + "a\r\nPing\n", 1), (std::vector<std::string>{"O:?:too_long", "L:Ping"}));
}

TEST(ProtocolFramer, PayloadsFollowTheirLineExactly) {
  const std::string model = "V1\n# a comment\r\n\n4\n0 0 0\n";  // newlines inside stay payload
  const std::string stream = "AddModel object=box format=cao bytes=" + std::to_string(model.size()) + "\n" + model +
                             "Ping\n"
                             "AddModel object=b@d format=cao bytes=5\nQuit\nPing\n";  // rejected: 5 bytes skipped
  const std::vector<std::string> expected = {"L:AddModel object=box format=cao bytes=" + std::to_string(model.size()),
                                             "P:" + model, "L:Ping",
                                             "L:AddModel object=b@d format=cao bytes=5", "L:Ping"};
  for (std::size_t chunk : {1u, 3u, 16u, 4096u}) {
    SCOPED_TRACE(chunk);
    EXPECT_EQ(run(stream, chunk), expected);
  }
}

TEST(ProtocolFramer, CutOffPayloadIsVisible) {
  vp::Framer f;
  f.feed("AddModel object=box format=cao bytes=100\nV1\n");
  auto frame = f.next();
  ASSERT_TRUE(frame && std::holds_alternative<vp::Framer::Line>(*frame));
  f.expect_payload(100);
  EXPECT_FALSE(f.next());
  EXPECT_EQ(f.payload_remaining(), 97u);
  EXPECT_EQ(f.buffered(), 3u);
  f.feed(std::string(97, 'z'));
  frame = f.next();
  ASSERT_TRUE(frame && std::holds_alternative<vp::Framer::Payload>(*frame));
  EXPECT_EQ(std::get<vp::Framer::Payload>(*frame).bytes, "V1\n" + std::string(97, 'z'));
  EXPECT_EQ(f.payload_remaining(), 0u);
  EXPECT_EQ(f.buffered(), 0u);
}
