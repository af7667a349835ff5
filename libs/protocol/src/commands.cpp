// v4r - robust model-based object tracking. MIT licence.
// Client commands: parse() and format(Command).
#include <string>

#include "lexer.hpp"
#include "v4r/protocol/protocol.hpp"

namespace v4r::protocol {
namespace {

using detail::Args;
using detail::Token;

template <class... F>
struct Overloaded : F... {
  using F::operator()...;
};
template <class... F>
Overloaded(F...) -> Overloaded<F...>;

ParseResult done(const Args& a, Command c) {
  if (!a.ok()) return a.error();
  return c;
}

ParseResult parse_name_only(Args& a, std::string_view key, bool remove) {
  a.check_keys({key});
  a.require({key});
  std::string n = a.name(key);
  if (remove) return done(a, RemoveObject{std::move(n)});
  return done(a, AddObject{std::move(n)});
}

ParseResult parse_add_object(Args& a) {
  a.check_keys({"name", "lifetime"});
  a.require({"name"});
  AddObject c;
  c.name = a.name("name");
  if (a.has("lifetime")) c.connection_lifetime = a.word("lifetime", {"server", "connection"}) == 1;
  return done(a, std::move(c));
}
ParseResult parse_remove_object(Args& a) { return parse_name_only(a, "name", true); }

ModelFormat read_format(Args& a) { return static_cast<ModelFormat>(a.word("format", {"cao", "obj", "ply", "stl"})); }

/// scale= of AddModel: model units to metres (0.001 for millimetres), default 1.
double read_scale(Args& a) {
  if (!a.has("scale")) return 1.0;
  const double s = a.number("scale");
  if (a.ok() && !(s > 0.0 && s <= 1e6))
    a.fail(code::kOutOfRange, "scale=: must be > 0 (model units to metres: 0.001 for millimetres)",
           a.find("scale")->value_column);
  return s;
}

ParseResult parse_add_model(Args& a) {
  a.check_keys({"object", "format", "bytes", "path", "scale"});
  a.require({"object"});
  const Token* bytes = a.find("bytes");
  const Token* path = a.find("path");
  if (a.ok() && bytes != nullptr && path != nullptr)
    a.fail(code::kBadArgument, "give either bytes= (the model text follows) or path=, not both", path->column);
  if (a.ok() && bytes == nullptr && path == nullptr)
    a.fail(code::kMissingArgument, "missing argument bytes= (the model text follows) or path=", 0);
  if (bytes != nullptr) a.require({"format"});
  std::string object = a.name("object");
  if (bytes != nullptr) {
    AddModelInline c;
    c.object = std::move(object);
    c.format = read_format(a);
    const std::uint64_t n = a.whole("bytes");
    if (a.ok() && n == 0) a.fail(code::kOutOfRange, "bytes=: must be at least 1", bytes->value_column);
    if (a.ok() && n > kMaxPayloadBytes)
      a.fail(code::kTooLarge,
             "bytes=: " + std::to_string(n) + " is beyond the limit of " + std::to_string(kMaxPayloadBytes) + " bytes",
             bytes->value_column);
    c.bytes = static_cast<std::size_t>(n);
    c.scale = read_scale(a);
    return done(a, std::move(c));
  }
  AddModelPath c;
  c.object = std::move(object);
  c.path = a.text("path");
  if (a.has("format")) c.format = read_format(a);
  c.scale = read_scale(a);
  return done(a, std::move(c));
}

ParseResult parse_add_feature(Args& a) {
  a.check_keys({"object", "type", "id", "p", "from", "to", "center", "normal", "radius"});
  a.require({"object", "type"});
  const std::size_t type = a.word("type", {"junction", "line", "circle"});
  if (!a.ok()) return a.error();
  if (type == 0) {
    a.check_keys({"object", "type", "id", "p"});
    a.require({"id", "p"});
    AddJunction c;
    c.object = a.name("object");
    c.id = a.name("id");
    c.p = a.vector<3>("p", "x,y,z");
    return done(a, std::move(c));
  }
  if (type == 1) {
    a.check_keys({"object", "type", "id", "from", "to"});
    a.require({"id", "from", "to"});
    AddLine c;
    c.object = a.name("object");
    c.id = a.name("id");
    c.from = a.name("from");
    c.to = a.name("to");
    if (a.ok() && c.from == c.to)
      a.fail(code::kBadArgument, "from= and to= name the same junction '" + c.from + "'", a.find("to")->value_column);
    return done(a, std::move(c));
  }
  a.check_keys({"object", "type", "id", "center", "normal", "radius"});
  a.require({"id", "center", "normal", "radius"});
  AddCircle c;
  c.object = a.name("object");
  c.id = a.name("id");
  c.center = a.vector<3>("center", "x,y,z");
  c.normal = a.vector<3>("normal", "x,y,z");
  if (a.ok() && c.normal[0] == 0.0 && c.normal[1] == 0.0 && c.normal[2] == 0.0)
    a.fail(code::kOutOfRange, "normal=: must not be the zero vector", a.find("normal")->value_column);
  c.radius = a.number("radius");
  if (a.ok() && !(c.radius > 0.0))
    a.fail(code::kOutOfRange, "radius=: must be > 0 (metres)", a.find("radius")->value_column);
  return done(a, std::move(c));
}

ParseResult parse_remove_feature(Args& a) {
  a.check_keys({"object", "id"});
  a.require({"object", "id"});
  RemoveFeature c;
  c.object = a.name("object");
  c.id = a.name("id");
  return done(a, std::move(c));
}

ParseResult parse_set_pose(Args& a) {
  a.check_keys({"object", "t", "r"});
  a.require({"object", "t", "r"});
  SetPose c;
  c.object = a.name("object");
  c.t = a.vector<3>("t", "tx,ty,tz");
  c.r = a.vector<3>("r", "rx,ry,rz");
  return done(a, std::move(c));
}

Topic read_topic(Args& a) { return static_cast<Topic>(a.word("what", {"ObjectPose", "SystemStatus"})); }

ParseResult parse_subscribe(Args& a) {
  a.check_keys({"what", "rate"});
  a.require({"what"});
  Subscribe c;
  c.what = read_topic(a);
  if (a.has("rate")) {
    c.rate_hz = a.number("rate") + 0.0;  // -0 -> 0
    if (a.ok() && c.rate_hz < 0.0)
      a.fail(code::kOutOfRange, "rate=: must be >= 0 Hz (0 = every frame)", a.find("rate")->value_column);
  }
  return done(a, c);
}

ParseResult parse_unsubscribe(Args& a) {
  a.check_keys({"what"});
  a.require({"what"});
  Unsubscribe c;
  c.what = read_topic(a);
  return done(a, c);
}

ParseResult parse_set_param(Args& a) {
  a.check_keys({"name", "value"});
  a.require({"name", "value"});
  SetParam c;
  c.name = a.name("name");
  c.value = a.text("value");
  return done(a, std::move(c));
}

ParseResult parse_get_param(Args& a) {
  a.check_keys({"name"});
  a.require({"name"});
  GetParam c;
  c.name = a.name("name");
  return done(a, std::move(c));
}

template <class C>
ParseResult parse_bare(Args& a) {
  a.check_keys({});
  return done(a, C{});
}

// The on|off word of Display and Log.
bool on_off(Args& a) {
  const auto words = a.positional();
  if (words.empty()) {
    a.fail(code::kMissingArgument, "missing on or off", 0);
    return false;
  }
  if (words[0]->value == "on") return true;
  if (words[0]->value != "off")
    a.fail(code::kBadArgument, std::string(1, '\'').append(detail::echo(words[0]->value)).append("' is not on|off"),
           words[0]->column);
  return false;
}

ParseResult parse_display(Args& a) {
  a.check_keys({}, 1);
  Display c;
  if (a.ok()) c.on = on_off(a);
  return done(a, c);
}

ParseResult parse_log(Args& a) {
  a.check_keys({"file"}, 1);
  Log c;
  if (a.ok()) c.on = on_off(a);
  if (a.ok() && a.has("file")) {
    if (!c.on) a.fail(code::kBadArgument, "file= goes with Log on only", a.find("file")->column);
    c.file = a.text("file");
  }
  return done(a, std::move(c));
}

ParseResult parse_auth(Args& a) {
  a.check_keys({"token"});
  a.require({"token"});
  Auth c;
  c.token = a.text("token");
  return done(a, std::move(c));
}

struct Entry {
  std::string_view name;
  ParseResult (*parse)(Args&);
};

constexpr Entry kCommands[] = {
    {"AddObject", parse_add_object},
    {"RemoveObject", parse_remove_object},
    {"AddModel", parse_add_model},
    {"AddFeature", parse_add_feature},
    {"RemoveFeature", parse_remove_feature},
    {"SetPose", parse_set_pose},
    {"Subscribe", parse_subscribe},
    {"Unsubscribe", parse_unsubscribe},
    {"SetParam", parse_set_param},
    {"GetParam", parse_get_param},
    {"ListParams", parse_bare<ListParams>},
    {"Start", parse_bare<Start>},
    {"Pause", parse_bare<Pause>},
    {"Display", parse_display},
    {"Log", parse_log},
    {"Ping", parse_bare<Ping>},
    {"Quit", parse_bare<Quit>},
    {"Auth", parse_auth},
};

bool equals_ignore_case(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    auto lower = [](char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; };
    if (lower(a[i]) != lower(b[i])) return false;
  }
  return true;
}

// bytes=N of an AddModel line that failed to parse, so that the server can skip the payload the
// client is about to send: the value of the single word "bytes=<digits>", if it is in range.
std::size_t payload_hint(std::string_view line) {
  std::size_t found = 0, count = 0;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && line[i] == ' ') ++i;
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ') ++j;
    const std::string_view w = line.substr(i, j - i);
    if (w.substr(0, 6) == "bytes=") {
      ++count;
      std::uint64_t n = 0;
      if (detail::parse_uint(w.substr(6), n) && n >= 1 && n <= kMaxPayloadBytes) found = n;
    }
    i = j;
  }
  return count == 1 ? found : 0;
}

std::string vec(const Vec3& v) {
  return format_number(v[0]) + "," + format_number(v[1]) + "," + format_number(v[2]);
}

}  // namespace

ParseResult parse(std::string_view line) {
  line = detail::strip_cr(line);
  std::vector<Token> tokens;
  ParseResult result = [&]() -> ParseResult {
    if (auto e = detail::lex(line, kMaxLineBytes, tokens)) return *e;
    const Token& first = tokens.front();
    const std::string cmd = detail::command_word(line);
    if (first.positional) {
      for (const Entry& e : kCommands) {
        if (e.name == first.value) {
          Args args(std::string(e.name), std::vector<Token>(tokens.begin() + 1, tokens.end()));
          return e.parse(args);
        }
      }
    }
    ParseError err;
    err.command = cmd;
    err.column = first.column;
    if (!first.positional) {
      err.code = std::string(code::kBadSyntax);
      err.message = "a line starts with a command name, not '" + detail::echo(first.key) + "='";
    } else {
      err.code = std::string(code::kUnknownCommand);
      err.message = "unknown command '" + detail::echo(first.value) + "'";
      for (const Entry& e : kCommands)
        if (equals_ignore_case(e.name, first.value))
          err.message += " (did you mean " + std::string(e.name) + "? command names are case-sensitive)";
    }
    err.message += " (column " + std::to_string(err.column) + ")";
    return err;
  }();
  if (auto* e = std::get_if<ParseError>(&result)) {
    if (e->command == "AddModel" && e->code != code::kTooLong) e->skip_bytes = payload_hint(line);
  }
  return result;
}

std::string_view command_name(const Command& c) {
  return std::visit(Overloaded{
                        [](const AddObject&) { return std::string_view("AddObject"); },
                        [](const RemoveObject&) { return std::string_view("RemoveObject"); },
                        [](const AddModelInline&) { return std::string_view("AddModel"); },
                        [](const AddModelPath&) { return std::string_view("AddModel"); },
                        [](const AddJunction&) { return std::string_view("AddFeature"); },
                        [](const AddLine&) { return std::string_view("AddFeature"); },
                        [](const AddCircle&) { return std::string_view("AddFeature"); },
                        [](const RemoveFeature&) { return std::string_view("RemoveFeature"); },
                        [](const SetPose&) { return std::string_view("SetPose"); },
                        [](const Subscribe&) { return std::string_view("Subscribe"); },
                        [](const Unsubscribe&) { return std::string_view("Unsubscribe"); },
                        [](const SetParam&) { return std::string_view("SetParam"); },
                        [](const GetParam&) { return std::string_view("GetParam"); },
                        [](const ListParams&) { return std::string_view("ListParams"); },
                        [](const Start&) { return std::string_view("Start"); },
                        [](const Pause&) { return std::string_view("Pause"); },
                        [](const Display&) { return std::string_view("Display"); },
                        [](const Log&) { return std::string_view("Log"); },
                        [](const Ping&) { return std::string_view("Ping"); },
                        [](const Quit&) { return std::string_view("Quit"); },
                        [](const Auth&) { return std::string_view("Auth"); },
                    },
                    c);
}

std::size_t payload_bytes(const Command& c) {
  const auto* m = std::get_if<AddModelInline>(&c);
  return m != nullptr ? m->bytes : 0;
}

std::string format(const Command& c) {
  const std::string name(command_name(c));
  const std::string args = std::visit(
      Overloaded{
          [](const AddObject& x) { return "name=" + x.name + (x.connection_lifetime ? " lifetime=connection" : ""); },
          [](const RemoveObject& x) { return "name=" + x.name; },
          [](const AddModelInline& x) {
            std::string s = "object=" + x.object + " format=" + std::string(to_string(x.format));
            if (x.scale != 1.0) s += " scale=" + format_number(x.scale);
            return s + " bytes=" + std::to_string(x.bytes);
          },
          [](const AddModelPath& x) {
            std::string s = "object=" + x.object + " path=" + format_value(x.path);
            if (x.format) s += " format=" + std::string(to_string(*x.format));
            if (x.scale != 1.0) s += " scale=" + format_number(x.scale);
            return s;
          },
          [](const AddJunction& x) { return "object=" + x.object + " type=junction id=" + x.id + " p=" + vec(x.p); },
          [](const AddLine& x) {
            return "object=" + x.object + " type=line id=" + x.id + " from=" + x.from + " to=" + x.to;
          },
          [](const AddCircle& x) {
            return "object=" + x.object + " type=circle id=" + x.id + " center=" + vec(x.center) +
                   " normal=" + vec(x.normal) + " radius=" + format_number(x.radius);
          },
          [](const RemoveFeature& x) { return "object=" + x.object + " id=" + x.id; },
          [](const SetPose& x) { return "object=" + x.object + " t=" + vec(x.t) + " r=" + vec(x.r); },
          [](const Subscribe& x) {
            std::string s = "what=" + std::string(to_string(x.what));
            if (x.rate_hz != 0.0) s += " rate=" + format_number(x.rate_hz);
            return s;
          },
          [](const Unsubscribe& x) { return "what=" + std::string(to_string(x.what)); },
          [](const SetParam& x) { return "name=" + x.name + " value=" + format_value(x.value); },
          [](const GetParam& x) { return "name=" + x.name; },
          [](const ListParams&) { return std::string(); },
          [](const Start&) { return std::string(); },
          [](const Pause&) { return std::string(); },
          [](const Display& x) { return std::string(x.on ? "on" : "off"); },
          [](const Log& x) {
            std::string s = x.on ? "on" : "off";
            if (x.on && !x.file.empty()) s += " file=" + format_value(x.file);
            return s;
          },
          [](const Ping&) { return std::string(); },
          [](const Quit&) { return std::string(); },
          [](const Auth& x) { return "token=" + format_value(x.token); },
      },
      c);
  return args.empty() ? name : name + " " + args;
}

}  // namespace v4r::protocol
