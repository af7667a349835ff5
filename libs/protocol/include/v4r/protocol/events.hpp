// v4r - robust model-based object tracking. MIT licence.
#pragma once

// Server -> client messages of the `v4r serve` protocol: events, replies and the greeting, with
// formatters (for the server) and parsers (for clients and tests). Include protocol.hpp.

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "v4r/protocol/protocol.hpp"

namespace v4r::protocol {

/// \brief `ObjectPose object=ID frame=N stamp=S t=tx,ty,tz q=qw,qx,qy,qz cov=<36> quality=Q
/// status=tracking|degraded|lost|failed [ref=FRAME]`: the pose of one object after one frame; or
/// `ObjectPose object=ID frame=N stamp=S quality=Q status=searching [ref=FRAME]` (no pose: not
/// found yet, or lost and searched again; t, q and cov are then left at their defaults). With
/// `ref=` (`v4r serve --scene`) the pose and covariance are T_ref_obj in the named reference frame
/// of the scene file; without it, T_cam_obj of the one camera.
struct ObjectPoseEvent {
  std::string object;
  std::uint64_t frame = 0;  ///< input frame index, counted from 0
  double stamp = 0.0;       ///< time stamp of that frame, seconds
  Vec3 t{};                 ///< T_cam_obj translation, metres
  std::array<double, 4> q{1.0, 0.0, 0.0, 0.0};  ///< T_cam_obj rotation, unit quaternion qw,qx,qy,qz
  /// 6x6 covariance, row-major, of the left tangent (v, w) of T_cam_obj (translation first):
  /// m^2, m*rad, rad^2.
  std::array<double, 36> cov{};
  double quality = 0.0;  ///< 0 (no support) .. 1 (all expected features found, no outliers)
  TrackStatus status = TrackStatus::kLost;
  std::string ref{};  ///< `ref=`: the reference frame of t, q and cov; empty: the camera (not sent)
  bool operator==(const ObjectPoseEvent&) const = default;
};

/// \brief One camera of a scene in SystemStatus: `NAME:FRAMES:ALIVE`.
struct CameraStatus {
  std::string name;
  std::uint64_t frames = 0;  ///< frames read from its input so far
  bool alive = true;         ///< its input still delivers frames (false: ended or failed)
  bool operator==(const CameraStatus&) const = default;
};

/// \brief `SystemStatus frame=N cycle_ms=X features_found=A features_used=B outliers=C
/// overruns=D [failed=F] [cameras=NAME:FRAMES:ALIVE,...]`: one vision cycle, summed over all
/// objects; `cameras=` (`v4r serve --scene`) per camera of the scene, in scene-file order.
struct SystemStatusEvent {
  std::uint64_t frame = 0;
  double cycle_ms = 0.0;  ///< wall time of the cycle, milliseconds
  std::uint64_t features_found = 0;
  std::uint64_t features_used = 0;  ///< found and used by the pose estimate
  std::uint64_t outliers = 0;       ///< found but rejected as outliers
  std::uint64_t overruns = 0;       ///< cycles over the time budget since the start
  std::uint64_t failed = 0;         ///< objects whose cycle failed (`failed=N`, sent only when > 0)
  std::vector<CameraStatus> cameras{};  ///< `cameras=`, sent only when not empty
  bool operator==(const SystemStatusEvent&) const = default;
};

/// \brief `Hello version=1 [auth=required]`: the greeting.
struct HelloMessage {
  int version = kVersion;
  bool auth_required = false;
  bool operator==(const HelloMessage&) const = default;
};

/// \brief `OK <Command> [word...] [key=value...]` or `ERR <Command> code=<word> msg="..." ...`.
struct Reply {
  bool ok = true;
  std::string command;
  std::string code;     ///< ERR only
  std::string message;  ///< ERR only, unescaped
  std::vector<std::string> words;  ///< words without '=' after the command (`OK Display on`)
  std::vector<std::pair<std::string, std::string>> fields;  ///< other key=value words, in order, unescaped
  /// Value of a field, or nullptr.
  [[nodiscard]] const std::string* find(std::string_view key) const;
  bool operator==(const Reply&) const = default;
};

/// \brief Any line a server sends.
using ServerMessage = std::variant<HelloMessage, Reply, ObjectPoseEvent, SystemStatusEvent>;

/// The event as one line (no LF). Numbers are shortest round-trip, so parsing gives back the
/// same doubles exactly.
std::string format(const ObjectPoseEvent& e);
std::string format(const SystemStatusEvent& e);

/// Inverse of format(). Every listed key is required, once; unknown keys are ignored (newer
/// servers may add some); numbers must be finite. No length limit applies to server lines.
std::variant<ObjectPoseEvent, ParseError> parse_object_pose(std::string_view line);
std::variant<SystemStatusEvent, ParseError> parse_system_status(std::string_view line);
/// Any server line: the greeting, a reply or an event (one trailing CR is stripped).
std::variant<ServerMessage, ParseError> parse_server_line(std::string_view line);

}  // namespace v4r::protocol
