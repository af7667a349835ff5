// v4r - robust model-based object tracking. MIT licence.
#pragma once

// The ASCII protocol of `v4r serve` (docs/protocol.md), as pure functions: text in, structs out,
// and back. No sockets, no threads, no state; nothing here throws on any input.

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

namespace v4r::protocol {

inline constexpr int kVersion = 1;                                 ///< sent in `Hello version=1`
inline constexpr std::size_t kMaxLineBytes = 4096;                 ///< longer lines: code=too_long
inline constexpr std::size_t kMaxPayloadBytes = std::size_t{16} << 20;  ///< AddModel bytes=N limit
inline constexpr std::size_t kMaxNameBytes = 64;                   ///< names and ids: [A-Za-z0-9_.-]{1,64}

/// Error code words of `ERR <Command> code=<word> msg="..."`. The first group is produced by
/// parse(); the second by the server when a well-formed command cannot be carried out.
namespace code {
inline constexpr std::string_view kEmptyLine = "empty_line";          ///< blank line (servers send no reply)
inline constexpr std::string_view kTooLong = "too_long";              ///< line longer than kMaxLineBytes
inline constexpr std::string_view kBadByte = "bad_byte";              ///< byte outside printable ASCII 0x20..0x7E
inline constexpr std::string_view kBadSyntax = "bad_syntax";          ///< not `Command word key=value ...`
inline constexpr std::string_view kUnknownCommand = "unknown_command";
inline constexpr std::string_view kUnknownArgument = "unknown_argument";  ///< key not defined for the command
inline constexpr std::string_view kDuplicateArgument = "duplicate_argument";
inline constexpr std::string_view kMissingArgument = "missing_argument";
inline constexpr std::string_view kBadArgument = "bad_argument";      ///< value not one of the allowed words
inline constexpr std::string_view kBadName = "bad_name";              ///< name/id not [A-Za-z0-9_.-]{1,64}
inline constexpr std::string_view kBadNumber = "bad_number";          ///< not a number / not a whole number
inline constexpr std::string_view kNotFinite = "not_finite";          ///< nan, inf, or overflows a double
inline constexpr std::string_view kBadVector = "bad_vector";          ///< wrong number of components
inline constexpr std::string_view kOutOfRange = "out_of_range";       ///< number outside its allowed range
inline constexpr std::string_view kTooLarge = "too_large";            ///< bytes=N beyond kMaxPayloadBytes
// Server-side codes (documented in docs/protocol.md; never returned by parse()).
inline constexpr std::string_view kUnauthorized = "unauthorized";     ///< Auth required first / wrong token
inline constexpr std::string_view kUnknownObject = "unknown_object";
inline constexpr std::string_view kExists = "exists";                 ///< object or feature id already used
inline constexpr std::string_view kUnknownFeature = "unknown_feature";
inline constexpr std::string_view kUnknownParam = "unknown_param";
inline constexpr std::string_view kBadValue = "bad_value";            ///< SetParam value rejected
inline constexpr std::string_view kBadModel = "bad_model";            ///< model text/file does not parse
inline constexpr std::string_view kUnsupported = "unsupported";       ///< e.g. a model format not built in
inline constexpr std::string_view kIoError = "io_error";              ///< file cannot be read/written
inline constexpr std::string_view kForbidden = "forbidden";            ///< a path outside the operator's folders
inline constexpr std::string_view kTruncated = "truncated";           ///< payload cut off
inline constexpr std::string_view kBusy = "busy";                     ///< server cannot take it now
inline constexpr std::string_view kInternal = "internal";
}  // namespace code

/// \brief Three numbers x,y,z (metres, or radians for a rotation vector).
using Vec3 = std::array<double, 3>;

/// \brief Model file formats accepted by AddModel.
enum class ModelFormat { kCao, kObj, kPly, kStl };
/// \brief Event streams a client can subscribe to.
enum class Topic { kObjectPose, kSystemStatus };
/// \brief Tracking state of one object in an ObjectPose event.
/// kSearching: the object has no pose yet (or lost and searched again); its ObjectPose has no t, q, cov.
enum class TrackStatus { kTracking, kDegraded, kLost, kFailed, kSearching };

std::string_view to_string(ModelFormat f);  ///< "cao", "obj", "ply", "stl"
std::string_view to_string(Topic t);        ///< "ObjectPose", "SystemStatus"
std::string_view to_string(TrackStatus s);  ///< "tracking", "degraded", "lost", "failed"

// ---------------------------------------------------------------------------------------------
// Commands (client -> server). One struct per command; field names follow the keys on the wire.

/// \brief `AddObject name=ID [lifetime=server|connection]`: a new, empty object. It belongs to the
/// server (default) or, with lifetime=connection, is removed when the client that added it disconnects.
struct AddObject {
  std::string name;
  bool connection_lifetime = false;
  bool operator==(const AddObject&) const = default;
};
/// \brief `RemoveObject name=ID`.
struct RemoveObject {
  std::string name;
  bool operator==(const RemoveObject&) const = default;
};
/// \brief `AddModel object=ID format=F [scale=S] bytes=N`: exactly N bytes of model text follow the line.
struct AddModelInline {
  std::string object;
  ModelFormat format = ModelFormat::kCao;
  std::size_t bytes = 0;  ///< 1..kMaxPayloadBytes
  double scale = 1.0;     ///< `scale=S`: model units to metres (0.001 for millimetres)
  bool operator==(const AddModelInline&) const = default;
};
/// \brief `AddModel object=ID path=FILE [format=F] [scale=S]`: a model file on the server's file system;
/// without format= the server deduces it from the extension.
struct AddModelPath {
  std::string object;
  std::string path;
  std::optional<ModelFormat> format;
  double scale = 1.0;  ///< `scale=S`: model units to metres (0.001 for millimetres)
  bool operator==(const AddModelPath&) const = default;
};
/// \brief `AddFeature object=ID type=junction id=J p=x,y,z`: a 3-D point, object frame, metres.
struct AddJunction {
  std::string object, id;
  Vec3 p{};
  bool operator==(const AddJunction&) const = default;
};
/// \brief `AddFeature object=ID type=line id=L from=J1 to=J2`: a straight edge between junctions.
struct AddLine {
  std::string object, id, from, to;
  bool operator==(const AddLine&) const = default;
};
/// \brief `AddFeature object=ID type=circle id=C center=x,y,z normal=x,y,z radius=R`: a circle in
/// the object frame (metres; normal need not be unit length but is not zero; radius > 0).
struct AddCircle {
  std::string object, id;
  Vec3 center{}, normal{};
  double radius = 0.0;
  bool operator==(const AddCircle&) const = default;
};
/// \brief `RemoveFeature object=ID id=F`.
struct RemoveFeature {
  std::string object, id;
  bool operator==(const RemoveFeature&) const = default;
};
/// \brief `SetPose object=ID t=tx,ty,tz r=rx,ry,rz`: T_cam_obj, translation in metres, rotation
/// vector (axis * angle, radians). The initial pose, or a hint after loss.
struct SetPose {
  std::string object;
  Vec3 t{}, r{};
  bool operator==(const SetPose&) const = default;
};
/// \brief `Subscribe what=ObjectPose|SystemStatus [rate=HZ]`; rate_hz 0 means every frame.
struct Subscribe {
  Topic what = Topic::kObjectPose;
  double rate_hz = 0.0;  ///< Hz, >= 0
  bool operator==(const Subscribe&) const = default;
};
/// \brief `Unsubscribe what=ObjectPose|SystemStatus`.
struct Unsubscribe {
  Topic what = Topic::kObjectPose;
  bool operator==(const Unsubscribe&) const = default;
};
/// \brief `SetParam name=K value=V`: V is text, validated by the server's parameter registry.
struct SetParam {
  std::string name, value;
  bool operator==(const SetParam&) const = default;
};
/// \brief `GetParam name=K`.
struct GetParam {
  std::string name;
  bool operator==(const GetParam&) const = default;
};
/// \brief `ListParams`.
struct ListParams {
  bool operator==(const ListParams&) const = default;
};
/// \brief `Start`: play the input (leave --paused).
struct Start {
  bool operator==(const Start&) const = default;
};
/// \brief `Pause`: hold the input at the current frame.
struct Pause {
  bool operator==(const Pause&) const = default;
};
/// \brief `Display on|off`: the monitoring overlay.
struct Display {
  bool on = false;
  bool operator==(const Display&) const = default;
};
/// \brief `Log on [file=F]` / `Log off`: per-cycle CSV log; file empty = the server's default.
struct Log {
  bool on = false;
  std::string file;
  bool operator==(const Log&) const = default;
};
/// \brief `Ping`.
struct Ping {
  bool operator==(const Ping&) const = default;
};
/// \brief `Quit`: the server replies `OK Quit` and closes this connection.
struct Quit {
  bool operator==(const Quit&) const = default;
};
/// \brief `Auth token=SECRET`.
struct Auth {
  std::string token;
  bool operator==(const Auth&) const = default;
};

/// \brief Any client command.
using Command = std::variant<AddObject, RemoveObject, AddModelInline, AddModelPath, AddJunction, AddLine,
                             AddCircle, RemoveFeature, SetPose, Subscribe, Unsubscribe, SetParam, GetParam,
                             ListParams, Start, Pause, Display, Log, Ping, Quit, Auth>;

/// \brief Why a line is not a valid command: everything needed for the `ERR` reply.
struct ParseError {
  std::string command;  ///< command word of the line if it looks like one, else "?" (for `ERR <Command>`)
  std::string code;     ///< one of the code:: words
  std::string message;  ///< for humans; names the key and the 1-based column
  std::size_t column = 0;      ///< 1-based byte column of the problem, 0 if none
  std::size_t skip_bytes = 0;  ///< payload bytes that still follow this line and must be discarded
  bool operator==(const ParseError&) const = default;
};

using ParseResult = std::variant<Command, ParseError>;

/// Parses one line (without LF; one trailing CR is stripped). Total: any bytes give a Command or
/// a ParseError. A blank line gives code::kEmptyLine (servers ignore it without a reply).
ParseResult parse(std::string_view line);

/// True for an empty line or one of spaces only (after stripping one trailing CR).
bool is_blank(std::string_view line);

/// Wire name of a command: "AddModel" for both AddModel forms, "AddFeature" for the three feature types.
std::string_view command_name(const Command& c);

/// Payload bytes that follow the command line (AddModelInline::bytes, else 0).
std::size_t payload_bytes(const Command& c);

/// The command as one protocol line (no LF); parse(format(c)) == c for every valid c. Numbers
/// are written in the shortest form that reads back to the same double.
std::string format(const Command& c);

// ---------------------------------------------------------------------------------------------
// Replies and text helpers (server -> client).

/// "Hello version=1", plus " auth=required" when the server wants `Auth` first.
std::string hello(bool auth_required = false);
/// "OK <command>" or "OK <command> <extra>" (extra: key=value words, see format_value()).
std::string format_ok(std::string_view command, std::string_view extra = {});
/// `ERR <command> code=<code> msg="<msg escaped>"`; an unusable command word becomes "?".
std::string format_err(std::string_view command, std::string_view code, std::string_view msg);
/// format_err(e.command, e.code, e.message).
std::string format_err(const ParseError& e);

/// `"..."` with \" and \\ escaped; bytes outside printable ASCII become '?', so the line stays valid.
std::string quote(std::string_view text);
/// The value as written after `key=`: bare when it is non-empty printable ASCII without spaces or
/// quotes, else quote(text).
std::string format_value(std::string_view text);
/// Shortest text that reads back to exactly x ("0.1", "1e-07", "-0"); "nan"/"inf"/"-inf" if not finite.
std::string format_number(double x);

/// True when text is a valid object, feature or parameter name: [A-Za-z0-9_.-]{1,64}.
bool is_valid_name(std::string_view text);

}  // namespace v4r::protocol

#include "v4r/protocol/events.hpp"  // IWYU pragma: export
