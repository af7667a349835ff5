// v4r - robust model-based object tracking. MIT licence.
// Text helpers shared by commands and events: names, numbers, quoting, OK/ERR/Hello lines.
#include <charconv>
#include <cmath>

#include "lexer.hpp"
#include "v4r/protocol/protocol.hpp"

namespace v4r::protocol {

std::string_view to_string(ModelFormat f) {
  switch (f) {
    case ModelFormat::kCao: return "cao";
    case ModelFormat::kObj: return "obj";
    case ModelFormat::kPly: return "ply";
    case ModelFormat::kStl: return "stl";
  }
  return "?";
}

std::string_view to_string(Topic t) {
  switch (t) {
    case Topic::kObjectPose: return "ObjectPose";
    case Topic::kSystemStatus: return "SystemStatus";
  }
  return "?";
}

std::string_view to_string(TrackStatus s) {
  switch (s) {
    case TrackStatus::kTracking: return "tracking";
    case TrackStatus::kDegraded: return "degraded";
    case TrackStatus::kLost: return "lost";
    case TrackStatus::kFailed: return "failed";
    case TrackStatus::kSearching: return "searching";
  }
  return "?";
}

bool is_valid_name(std::string_view text) {
  if (text.empty() || text.size() > kMaxNameBytes) return false;
  for (char c : text) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                    c == '.' || c == '-';
    if (!ok) return false;
  }
  return true;
}

bool is_blank(std::string_view line) {
  for (char c : detail::strip_cr(line))
    if (c != ' ') return false;
  return true;
}

std::string format_number(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);  // shortest round-trip
  return std::string(buf, r.ptr);
}

std::string quote(std::string_view text) {
  std::string s;
  s.reserve(text.size() + 2);
  s += '"';
  for (char c : text) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      s += '\\';
      s += c;
    } else if (u < 0x20 || u > 0x7E) {
      s += '?';
    } else {
      s += c;
    }
  }
  s += '"';
  return s;
}

std::string format_value(std::string_view text) {
  bool bare = !text.empty();
  for (char c : text) {
    const auto u = static_cast<unsigned char>(c);
    bare = bare && u > 0x20 && u <= 0x7E && c != '"';
  }
  return bare ? std::string(text) : quote(text);
}

std::string hello(bool auth_required) {
  return "Hello version=" + std::to_string(kVersion) + (auth_required ? " auth=required" : "");
}

namespace {
// A command word usable in a reply line: [A-Za-z][A-Za-z0-9_]{0,63}, else "?".
std::string reply_word(std::string_view command) {
  const std::string w = detail::command_word(command);
  return w.size() == command.size() ? w : std::string("?");
}
}  // namespace

std::string format_ok(std::string_view command, std::string_view extra) {
  std::string s = "OK " + reply_word(command);
  if (!extra.empty()) {
    s += ' ';
    s += extra;
  }
  return s;
}

std::string format_err(std::string_view command, std::string_view code, std::string_view msg) {
  std::string c = is_valid_name(code) ? std::string(code) : std::string(code::kInternal);
  return "ERR " + reply_word(command) + " code=" + c + " msg=" + quote(msg);
}

std::string format_err(const ParseError& e) { return format_err(e.command, e.code, e.message); }

}  // namespace v4r::protocol
