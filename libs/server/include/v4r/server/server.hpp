// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "v4r/core/clock.hpp"
#include "v4r/core/expected.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/pipeline/object_search.hpp"
#include "v4r/scene/scene.hpp"
#include "v4r/server/tracking_service.hpp"
#include "v4r/pipeline/vision_cycle.hpp"

namespace v4r::server {

struct FrameEvents;

/// \brief Everything `v4r serve` is configured with (defaults in code; see docs/protocol.md).
struct ServerOptions {
  geometry::PinholeCamera camera;  ///< calibration of the input
  std::string input;               ///< image folder, printf pattern or video (io::FrameSource::open)
  double fps = 30.0;               ///< frames per second the input is played at; <= 0: as fast as processed
  bool paused = false;             ///< hold at frame 0 until a client sends Start
  std::string bind = "127.0.0.1";  ///< listening address; anything but loopback requires a token
  std::uint16_t port = 5757;       ///< protocol port; 0 picks a free one (see Server::port())
  int http_port = -1;              ///< monitoring page port; < 0 off, 0 picks a free one
  std::string token;               ///< non-empty: clients must send `Auth token=...` first (any address)
  std::size_t max_clients = 200;   ///< more connections are refused with `ERR ? code=busy`
  std::size_t max_replies = 256;   ///< replies waiting for a client that does not read; more: disconnect
  std::size_t event_backlog = 64;  ///< unsent events kept per stream and object for a client that is behind (older ones are dropped)
  std::chrono::milliseconds write_stall_timeout{30000};  ///< a write making no progress this long: disconnect
  std::chrono::milliseconds auth_timeout{10000};         ///< time to authenticate when a token is set
  std::chrono::milliseconds close_grace{2000};           ///< time a final ERR gets to reach a client before close
  pipeline::CycleParams params;    ///< initial tracker parameters
  pipeline::ObjectSearchParams search;  ///< search.*: objects without SetPose, and lost ones, are searched
  detection::DetectorParams detect;     ///< detect.*: the search's detector
  std::string cache_dir;                ///< the detector's template cache (empty: the default)
  std::string log_file = "v4r_cycles.csv";  ///< `Log on` without file= (the operator's choice: not bounded by log_dir)
  std::vector<std::string> data_dirs;  ///< folders `AddModel path=` may read (relative: inside the first); empty: the working folder
  std::string log_dir;                 ///< folder `Log on file=` may write; empty: `file=` is refused
  bool handle_signals = true;      ///< SIGINT / SIGTERM stop run()
  /// Test seam (no command-line option, no protocol command): called on the tracking thread with
  /// each tracked object's name at the start of its cycle; whatever it throws is a fault in that
  /// object's cycle. Empty in production.
  std::function<void(const std::string& object)> object_hook;
  /// Middleware adapters (ROS 2 on the wire): called on the tracking thread with each frame's
  /// events, after the vision cycle; must not block (and what it throws is caught and counted as
  /// a fault). Empty: none.
  std::function<void(const FrameEvents& frame)> frame_observer;
};

/// \brief `v4r serve --scene`: every camera of a scene file with its input, the reference frame
/// that ObjectPose names, and the objects tracked from the first frame.
struct ServeScene {
  std::vector<scene::Camera> cameras;                      ///< with T_ref_cam, in scene-file order
  std::vector<std::unique_ptr<io::FrameSource>> inputs;    ///< one per camera, read in step
  std::string reference_frame;                             ///< ObjectPose `ref=`
  std::vector<StartObject> objects;
};

/// \brief Counters of a running server (read from any thread).
struct ServerStats {
  std::int64_t frames = 0;           ///< frames processed by the vision cycle
  std::size_t clients = 0;           ///< connected protocol clients
  std::uint64_t connections = 0;     ///< accepted connections so far
  std::uint64_t refused = 0;         ///< connections refused (max_clients)
  std::uint64_t disconnected_slow = 0;  ///< clients dropped (or being dropped) for not reading (reply overflow, stalled write)
  int objects_failed = 0;            ///< objects whose cycle threw (status=failed)
  std::uint64_t faults = 0;          ///< faults caught outside one object's cycle (frames, commands, network handlers)
  bool tracking_alive = true;        ///< false once the tracking thread stopped on an error
  std::size_t peak_write_lines = 0;  ///< most lines handed to one client's socket in one write (outbox high-water mark)
  std::size_t peak_write_bytes = 0;  ///< most bytes in one such write
  bool paused = false;
  bool end_of_input = false;
};

/// \brief `v4r serve`: the TCP server of the v4r protocol (docs/protocol.md). One network thread
/// (Asio) serves every client: line-at-a-time reads capped at protocol::kMaxLineBytes, a bounded
/// outbox per client (replies in order, newest event per object), write deadlines. The tracking
/// thread (TrackingService) plays the input through the vision cycle and applies the clients'
/// scene commands between frames; model files are parsed on a third thread. Optionally an HTTP
/// monitor (`/`, `/stream.mjpg`, `/status.json`) on a second port. The only place with sockets.
///
/// Behaviour: objects belong to the server, not to the client that made them (any client may
/// change or remove them; they stay when their client leaves). `Start`/`Pause` hold the input
/// before its next frame; at the end of the input no more events are sent and the server keeps
/// serving (commands still work) until it is stopped. Events go to every subscribed client; a
/// slow one gets the newest pose per object, a client that leaves more than max_replies replies
/// unread is dropped after a last `ERR ? code=busy`, and one whose writes make no progress for
/// write_stall_timeout is dropped after `ERR ? code=busy msg="not reading..."` (sent if it reads
/// within close_grace).
///
/// Files: clients reach only the operator's folders (data_dirs for models and their includes,
/// log_dir for `Log on file=`); anything else gets `code=forbidden` and is neither read nor
/// created. Faults: see TrackingService; the network thread logs a handler that throws and goes on.
class Server {
 public:
  /// Validates the options (a non-loopback bind needs a token), opens the input (checking its
  /// first frame against the calibration) and binds the ports. Nothing runs yet.
  static Expected<std::unique_ptr<Server>> create(ServerOptions opt);
  /// The same with a scene of several cameras (`opt.camera` and `opt.input` are not used).
  static Expected<std::unique_ptr<Server>> create(ServerOptions opt, ServeScene scene);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// The bound protocol port (useful with port 0).
  [[nodiscard]] std::uint16_t port() const;
  /// The bound HTTP port, or 0 without the monitor.
  [[nodiscard]] std::uint16_t http_port() const;

  /// Starts the tracking thread and serves on the calling thread until stop() or (with
  /// handle_signals) SIGINT/SIGTERM. Returns the exit code (0).
  int run();
  /// Starts everything on background threads and returns (tests, embedding).
  void start();
  /// Stops serving: closes the ports and every connection, stops the threads. Thread-safe,
  /// idempotent; waits for the background threads when called from another thread.
  void stop();

  [[nodiscard]] ServerStats stats() const;
  /// When each frame was handed to the vision cycle (steady clock), by frame index: the start
  /// of the frame-to-ObjectPose latency.
  [[nodiscard]] std::vector<Clock::time_point> frame_release_times() const;

 private:
  struct Impl;
  explicit Server(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace v4r::server
