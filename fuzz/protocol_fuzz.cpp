// v4r - robust model-based object tracking. MIT licence.
// libFuzzer target for the ASCII protocol (issue 4): arbitrary bytes, split at LF, go to parse(),
// to parse_server_line() and through a Framer. Besides "no crash, no sanitizer report" it checks
// the properties the protocol promises, and aborts when one fails:
//   - parse(format(c)) == c and format() is canonical, for every command parse() accepts;
//   - the ERR line built from any ParseError reads back with the same command, code and message;
//   - blank lines, and only those, give code empty_line;
//   - events that parse are formatted back to text that parses to the same event;
//   - the Framer returns the same lines for any chunking and never holds more than one line.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "v4r/protocol/framer.hpp"
#include "v4r/protocol/protocol.hpp"

namespace vp = v4r::protocol;

namespace {

void check(bool ok, const char* what, std::string_view line) {
  if (ok) return;
  std::fprintf(stderr, "property violated: %s\nline (%zu bytes): %.*s\n", what, line.size(),
               static_cast<int>(line.size() > 300 ? 300 : line.size()), line.data());
  std::abort();
}

void check_command_line(std::string_view line) {
  const vp::ParseResult r = vp::parse(line);
  if (const auto* c = std::get_if<vp::Command>(&r)) {
    const std::string text = vp::format(*c);
    const vp::ParseResult again = vp::parse(text);
    const auto* c2 = std::get_if<vp::Command>(&again);
    check(c2 != nullptr, "format(parse(line)) does not parse", text);
    check(*c2 == *c, "parse(format(c)) != c", text);
    check(vp::format(*c2) == text, "format is not canonical", text);
    check(!vp::is_blank(line), "blank line parsed as a command", line);
    return;
  }
  const auto& e = std::get<vp::ParseError>(r);
  check((e.code == "empty_line") == vp::is_blank(line), "empty_line code disagrees with is_blank", line);
  check(e.skip_bytes <= vp::kMaxPayloadBytes, "skip_bytes beyond the payload limit", line);
  const std::string err = vp::format_err(e);
  const auto back = vp::parse_server_line(err);
  const auto* msg = std::get_if<vp::ServerMessage>(&back);
  check(msg != nullptr, "ERR line does not parse", err);
  const auto* reply = std::get_if<vp::Reply>(msg);
  check(reply != nullptr && !reply->ok, "ERR line is not an ERR reply", err);
  check(reply->command == e.command && reply->code == e.code, "ERR command/code changed", err);
  check(reply->message == e.message, "ERR message changed", err);
}

void check_server_line(std::string_view line) {
  const auto r = vp::parse_server_line(line);
  const auto* msg = std::get_if<vp::ServerMessage>(&r);
  if (msg == nullptr) return;
  if (const auto* e = std::get_if<vp::ObjectPoseEvent>(msg)) {
    const std::string text = vp::format(*e);
    const auto back = vp::parse_object_pose(text);
    check(std::holds_alternative<vp::ObjectPoseEvent>(back) && std::get<vp::ObjectPoseEvent>(back) == *e,
          "ObjectPose round trip", text);
  } else if (const auto* s = std::get_if<vp::SystemStatusEvent>(msg)) {
    const std::string text = vp::format(*s);
    const auto back = vp::parse_system_status(text);
    check(std::holds_alternative<vp::SystemStatusEvent>(back) && std::get<vp::SystemStatusEvent>(back) == *s,
          "SystemStatus round trip", text);
  }
}

// Runs the stream through a Framer in chunks, asking for payloads as a server does.
std::vector<std::string> frames(std::string_view stream, std::size_t chunk) {
  vp::Framer f;
  std::vector<std::string> out;
  for (std::size_t i = 0; i < stream.size(); i += chunk) {
    f.feed(stream.substr(i, chunk));
    while (auto frame = f.next()) {
      if (const auto* l = std::get_if<vp::Framer::Line>(&*frame)) {
        check(l->text.size() <= vp::kMaxLineBytes, "Framer returned an over-long line", l->text);
        out.push_back("L" + l->text);
        const vp::ParseResult r = vp::parse(l->text);
        if (const auto* c = std::get_if<vp::Command>(&r)) {
          if (vp::payload_bytes(*c) > 0) f.expect_payload(vp::payload_bytes(*c));
        } else if (std::get<vp::ParseError>(r).skip_bytes > 0) {
          f.expect_payload(std::get<vp::ParseError>(r).skip_bytes, false);
        }
      } else if (const auto* o = std::get_if<vp::Framer::Overlong>(&*frame)) {
        out.push_back("O" + o->error.command);
      } else {
        out.push_back("P" + std::get<vp::Framer::Payload>(*frame).bytes);
      }
    }
    check(f.payload_remaining() > 0 || f.buffered() <= vp::kMaxLineBytes + 1, "Framer holds more than one line",
          stream.substr(0, 200));
  }
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  std::size_t start = 0;
  while (start <= input.size()) {
    std::size_t end = input.find('\n', start);
    if (end == std::string_view::npos) end = input.size();
    const std::string_view line = input.substr(start, end - start);
    check_command_line(line);
    check_server_line(line);
    start = end + 1;
  }
  // Chunking must not change what the Framer returns.
  const std::size_t chunk = size > 0 ? 1 + data[0] % 17 : 1;
  check(frames(input, chunk) == frames(input, size + 1), "Framer output depends on chunking", input.substr(0, 200));
  return 0;
}
