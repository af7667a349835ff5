// v4r - robust model-based object tracking. MIT licence.
#pragma once

// Internal: one protocol connection, driven by the network thread.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <asio.hpp>

#include "v4r/protocol/framer.hpp"
#include "v4r/protocol/protocol.hpp"
#include "v4r/server/model_loading.hpp"
#include "v4r/server/outbox.hpp"
#include "v4r/server/server.hpp"
#include "v4r/server/tracking_service.hpp"

namespace v4r::server {

class Session;

/// \brief What a Session needs from the server (all on the network thread).
class SessionHost {
 public:
  virtual ~SessionHost() = default;
  virtual asio::io_context& io() = 0;
  virtual TrackingService& service() = 0;
  virtual Worker& loader() = 0;
  virtual const ServerOptions& options() const = 0;
  /// The folders `AddModel path=` and `.cao` includes may read.
  virtual const PathPolicy& data_dirs() const = 0;
  /// Called once when the session closed.
  virtual void session_closed(const std::shared_ptr<Session>& s) = 0;
  /// Called once when the session decided to drop its client for not reading (before the close).
  virtual void dropping_slow_client() = 0;
  /// Called before each write with what it holds: the outbox's high-water mark.
  virtual void note_write(std::size_t lines, std::size_t bytes) = 0;
  /// Reserves memory for an inline model of `bytes` from the server-wide budget (false: over it).
  virtual bool reserve_payload(std::size_t bytes) = 0;
  /// Returns a reservation (any thread).
  virtual void release_payload(std::size_t bytes) = 0;
};

/// \brief One client connection: reads lines (at most protocol::kMaxLineBytes) and payloads,
/// parses them with v4r::protocol, answers every command exactly once and in order (a command
/// handed to the tracking thread or the model loader holds the following ones back until its
/// reply is queued), and writes replies and subscribed events from its Outbox. Lives on the
/// network thread; kept alive by its pending operations and the server's session list.
class Session : public std::enable_shared_from_this<Session> {
 public:
  Session(asio::ip::tcp::socket socket, SessionHost& host);

  /// Greets the client and starts reading.
  void start();
  /// Greets with `ERR ? code=busy` instead and closes (too many clients).
  void refuse(std::string_view why);
  /// Queues this frame's events the client subscribed to (newest per object) and writes.
  void deliver(const FrameEvents& ev);
  /// Closes the connection now.
  void close();
  [[nodiscard]] bool closed() const { return closed_; }

 private:
  struct Subscription {
    bool on = false;
    double interval_s = 0.0;  ///< 1 / rate, 0: every frame
    double last_stamp = 0.0;
    bool sent_any = false;
  };

  void start_read();
  void on_read(const asio::error_code& ec, std::size_t n);
  void process();
  void handle_line(std::string_view line);
  void handle_command(const protocol::Command& cmd);
  void handle_payload(std::string bytes);
  TrackingService::ReplyFn deferred_reply();
  void finish_command(std::string line);
  void reply(std::string line);
  void drop_slow(std::string_view why);
  void flush();
  void on_written(const asio::error_code& ec, std::uint64_t gen);
  void arm_write_timer(std::chrono::milliseconds d);
  void close_gracefully();
  void release();
  void drain();
  bool accept(Subscription& s, double stamp);

  SessionHost& host_;
  asio::ip::tcp::socket socket_;
  asio::steady_timer write_timer_, auth_timer_;
  std::array<char, 64 * 1024> chunk_{};
  protocol::Framer framer_;         // received bytes -> lines and payloads
  std::optional<protocol::AddModelInline> payload_cmd_;  // waiting for its payload (reserved)
  std::vector<std::string> owned_;  // objects added with lifetime=connection: removed at close
  bool auth_required_ = false, authed_ = false;
  int auth_failures_ = 0;
  bool reading_ = false, busy_ = false, writing_ = false, closing_ = false, closed_ = false, slow_ = false;
  bool shut_down_ = false, released_ = false;
  std::uint64_t write_gen_ = 0;
  Outbox outbox_;
  std::vector<SharedLine> sending_;
  std::vector<asio::const_buffer> buffers_;
  Subscription pose_sub_, status_sub_;
};

}  // namespace v4r::server
