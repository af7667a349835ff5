// v4r - robust model-based object tracking. MIT licence.
// Server -> client lines: events, replies, greeting.
#include <charconv>
#include <climits>
#include <optional>
#include <unordered_set>

#include "lexer.hpp"
#include "v4r/protocol/protocol.hpp"

namespace v4r::protocol {
namespace {

using detail::Args;
using detail::Token;

template <std::size_t N>
std::string join(const std::array<double, N>& v) {
  std::string s;
  for (std::size_t i = 0; i < N; ++i) {
    if (i > 0) s += ',';
    s += format_number(v[i]);
  }
  return s;
}

/// `NAME:FRAMES:ALIVE,...` (the name is everything before the last two colons).
std::optional<std::vector<CameraStatus>> parse_cameras(std::string_view text) {
  std::vector<CameraStatus> out;
  for (bool more = true; more;) {
    const std::size_t comma = text.find(',');
    const std::string_view item = text.substr(0, comma);
    more = comma != std::string_view::npos;
    if (more) text = text.substr(comma + 1);
    const std::size_t c2 = item.rfind(':');
    if (c2 == std::string_view::npos || c2 == 0) return std::nullopt;
    const std::size_t c1 = item.rfind(':', c2 - 1);
    if (c1 == std::string_view::npos || c1 == 0) return std::nullopt;
    const std::string_view frames = item.substr(c1 + 1, c2 - c1 - 1), alive = item.substr(c2 + 1);
    CameraStatus c;
    c.name = std::string(item.substr(0, c1));
    const auto r = std::from_chars(frames.data(), frames.data() + frames.size(), c.frames);
    if (frames.empty() || r.ec != std::errc() || r.ptr != frames.data() + frames.size()) return std::nullopt;
    if (alive != "0" && alive != "1") return std::nullopt;
    c.alive = alive == "1";
    out.push_back(std::move(c));
  }
  return out;
}

std::string format_cameras(const std::vector<CameraStatus>& cams) {
  std::string s;
  for (const CameraStatus& c : cams) {
    if (!s.empty()) s += ',';
    s += c.name + ':' + std::to_string(c.frames) + (c.alive ? ":1" : ":0");
  }
  return s;
}

ParseError syntax_error(std::string command, std::string_view code, std::string message, std::size_t column) {
  ParseError e;
  e.command = std::move(command);
  e.code = std::string(code);
  e.message = std::move(message);
  if (column > 0) e.message += " (column " + std::to_string(column) + ")";
  e.column = column;
  return e;
}

// Lexes a server line (no length limit) and checks that it starts with a word.
std::optional<ParseError> lex_server(std::string_view line, std::vector<Token>& tokens) {
  if (auto e = detail::lex(detail::strip_cr(line), 0, tokens)) return e;
  if (!tokens.front().positional)
    return syntax_error(detail::command_word(line), code::kBadSyntax, "a line starts with a message name",
                        tokens.front().column);
  return std::nullopt;
}

std::variant<ObjectPoseEvent, ParseError> object_pose_from(const std::vector<Token>& tokens) {
  Args a("ObjectPose", std::vector<Token>(tokens.begin() + 1, tokens.end()));
  a.check_keys({"object", "frame", "stamp", "t", "q", "cov", "quality", "status", "ref"}, 0, true);
  a.require({"object", "frame", "stamp", "quality", "status"});
  ObjectPoseEvent e;
  e.object = a.name("object");
  e.frame = a.whole("frame");
  e.stamp = a.number("stamp");
  e.quality = a.number("quality");
  e.status = static_cast<TrackStatus>(a.word("status", {"tracking", "degraded", "lost", "failed", "searching"}));
  if (e.status != TrackStatus::kSearching) {  // a searched object has no pose
    a.require({"t", "q", "cov"});
    e.t = a.vector<3>("t", "tx,ty,tz");
    e.q = a.vector<4>("q", "qw,qx,qy,qz");
    e.cov = a.vector<36>("cov", "(6x6 row-major)");
  }
  if (a.has("ref")) e.ref = a.text("ref");
  if (!a.ok()) return a.error();
  return e;
}

std::variant<SystemStatusEvent, ParseError> system_status_from(const std::vector<Token>& tokens) {
  Args a("SystemStatus", std::vector<Token>(tokens.begin() + 1, tokens.end()));
  a.check_keys({"frame", "cycle_ms", "features_found", "features_used", "outliers", "overruns", "failed", "cameras"}, 0,
               true);
  a.require({"frame", "cycle_ms", "features_found", "features_used", "outliers", "overruns"});
  SystemStatusEvent e;
  e.frame = a.whole("frame");
  e.cycle_ms = a.number("cycle_ms");
  e.features_found = a.whole("features_found");
  e.features_used = a.whole("features_used");
  e.outliers = a.whole("outliers");
  e.overruns = a.whole("overruns");
  if (a.has("failed")) e.failed = a.whole("failed");
  if (a.has("cameras")) {
    auto cams = parse_cameras(a.text("cameras"));
    if (!cams) {
      a.fail(code::kBadArgument, "cameras=: expected NAME:FRAMES:ALIVE,... (ALIVE 0 or 1)", 0);
    } else {
      e.cameras = std::move(*cams);
    }
  }
  if (!a.ok()) return a.error();
  return e;
}

std::variant<ServerMessage, ParseError> hello_from(const std::vector<Token>& tokens) {
  Args a("Hello", std::vector<Token>(tokens.begin() + 1, tokens.end()));
  a.check_keys({"version", "auth"}, 0, true);
  a.require({"version"});
  HelloMessage h;
  const std::uint64_t v = a.whole("version");
  if (a.ok() && v > static_cast<std::uint64_t>(INT_MAX))
    a.fail(code::kOutOfRange, "version=: too large", a.find("version")->value_column);
  h.version = static_cast<int>(v);
  if (a.has("auth")) h.auth_required = a.word("auth", {"required", "none"}) == 0;
  if (!a.ok()) return a.error();
  return ServerMessage{h};
}

std::variant<ServerMessage, ParseError> reply_from(const std::vector<Token>& tokens, bool ok) {
  const std::string kind = ok ? "OK" : "ERR";
  if (tokens.size() < 2 || !tokens[1].positional || detail::command_word(tokens[1].value) != tokens[1].value)
    return syntax_error(kind, code::kBadSyntax, kind + " must be followed by a command word",
                        tokens.size() < 2 ? 0 : tokens[1].column);
  Reply r;
  r.ok = ok;
  r.command = tokens[1].value;
  bool has_code = false, has_msg = false;
  std::unordered_set<std::string_view> keys;
  for (std::size_t i = 2; i < tokens.size(); ++i) {
    const Token& t = tokens[i];
    if (t.positional) {
      r.words.push_back(t.value);
      continue;
    }
    if (!keys.insert(t.key).second)
      return syntax_error(kind, code::kDuplicateArgument, t.key + "= given twice", t.column);
    if (!ok && t.key == "code") {
      if (!is_valid_name(t.value))
        return syntax_error(kind, code::kBadName, "code=: '" + detail::echo(t.value) + "' is not a code word",
                            t.value_column);
      r.code = t.value;
      has_code = true;
    } else if (!ok && t.key == "msg") {
      r.message = t.value;
      has_msg = true;
    } else {
      r.fields.emplace_back(t.key, t.value);
    }
  }
  if (!ok && !has_code) return syntax_error(kind, code::kMissingArgument, "missing argument code=", 0);
  if (!ok && !has_msg) return syntax_error(kind, code::kMissingArgument, "missing argument msg=", 0);
  return ServerMessage{std::move(r)};
}

}  // namespace

const std::string* Reply::find(std::string_view key) const {
  for (const auto& [k, v] : fields)
    if (k == key) return &v;
  return nullptr;
}

std::string format(const ObjectPoseEvent& e) {
  const std::string pose = e.status == TrackStatus::kSearching
                               ? std::string()
                               : " t=" + join(e.t) + " q=" + join(e.q) + " cov=" + join(e.cov);
  std::string s = "ObjectPose object=" + format_value(e.object) + " frame=" + std::to_string(e.frame) +
                  " stamp=" + format_number(e.stamp) + pose + " quality=" + format_number(e.quality) +
                  " status=" + std::string(to_string(e.status));
  if (!e.ref.empty()) s += " ref=" + format_value(e.ref);
  return s;
}

std::string format(const SystemStatusEvent& e) {
  return "SystemStatus frame=" + std::to_string(e.frame) + " cycle_ms=" + format_number(e.cycle_ms) +
         " features_found=" + std::to_string(e.features_found) + " features_used=" + std::to_string(e.features_used) +
         " outliers=" + std::to_string(e.outliers) + " overruns=" + std::to_string(e.overruns) +
         (e.failed > 0 ? " failed=" + std::to_string(e.failed) : std::string()) +
         (e.cameras.empty() ? std::string() : " cameras=" + format_value(format_cameras(e.cameras)));
}

std::variant<ObjectPoseEvent, ParseError> parse_object_pose(std::string_view line) {
  std::vector<Token> tokens;
  if (auto e = lex_server(line, tokens)) return *e;
  if (tokens.front().value != "ObjectPose")
    return syntax_error(detail::command_word(line), code::kUnknownCommand, "not an ObjectPose line", 1);
  return object_pose_from(tokens);
}

std::variant<SystemStatusEvent, ParseError> parse_system_status(std::string_view line) {
  std::vector<Token> tokens;
  if (auto e = lex_server(line, tokens)) return *e;
  if (tokens.front().value != "SystemStatus")
    return syntax_error(detail::command_word(line), code::kUnknownCommand, "not a SystemStatus line", 1);
  return system_status_from(tokens);
}

std::variant<ServerMessage, ParseError> parse_server_line(std::string_view line) {
  std::vector<Token> tokens;
  if (auto e = lex_server(line, tokens)) return *e;
  const std::string& word = tokens.front().value;
  if (word == "OK") return reply_from(tokens, true);
  if (word == "ERR") return reply_from(tokens, false);
  if (word == "Hello") return hello_from(tokens);
  if (word == "ObjectPose") {
    auto r = object_pose_from(tokens);
    if (auto* e = std::get_if<ParseError>(&r)) return *e;
    return ServerMessage{std::get<ObjectPoseEvent>(std::move(r))};
  }
  if (word == "SystemStatus") {
    auto r = system_status_from(tokens);
    if (auto* e = std::get_if<ParseError>(&r)) return *e;
    return ServerMessage{std::get<SystemStatusEvent>(std::move(r))};
  }
  return syntax_error(detail::command_word(line), code::kUnknownCommand,
                      "unknown server message '" + detail::echo(word) + "'", 1);
}

}  // namespace v4r::protocol
