// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace v4r::server {

/// A line ready to send (with its line end), shared between the clients that receive it.
using SharedLine = std::shared_ptr<const std::string>;

/// \brief What waits to be sent to one client: a bounded FIFO of replies (every reply is sent,
/// in order) and per event key (an object's ObjectPose, the SystemStatus) the newest
/// `event_depth` unsent events: a newer event pushes out the oldest unsent one of its key, so a
/// slow client gets the newest state instead of a growing queue, while a client that is only
/// briefly behind (a write still in flight for a few frames) loses nothing. Memory is bounded by
/// max_replies plus event_depth times the number of keys. Not thread-safe (owned by the thread
/// that writes to the client).
class Outbox {
 public:
  explicit Outbox(std::size_t max_replies = 256, std::size_t event_depth = 1)
      : max_replies_(max_replies), event_depth_(event_depth > 0 ? event_depth : 1) {}

  /// Queues a reply. Returns false (and drops the reply) when max_replies are already waiting:
  /// the client does not read and is to be disconnected.
  bool push_reply(SharedLine line);
  /// Stores the newest event under `key` (e.g. "P box", "S"); when `event_depth` events of that
  /// key wait already, the oldest of them is dropped (counted in events_replaced()).
  void put_event(const std::string& key, SharedLine line);
  /// Forgets unsent events whose key starts with `prefix` (after an Unsubscribe).
  void drop_events(const std::string& prefix);

  [[nodiscard]] bool empty() const { return replies_.empty() && pending_events_ == 0; }
  [[nodiscard]] std::size_t replies_waiting() const { return replies_.size(); }
  /// Events replaced before they were sent (a measure of how slow the client is).
  [[nodiscard]] std::uint64_t events_replaced() const { return replaced_; }

  /// Moves everything waiting into `out` in sending order: replies first, then the events, oldest
  /// first (round by round: the oldest of each key, in the order the keys first appeared, then
  /// the next). Returns the number of lines appended.
  std::size_t take(std::vector<SharedLine>& out);

 private:
  std::size_t max_replies_, event_depth_;
  std::deque<SharedLine> replies_;
  std::vector<std::pair<std::string, std::deque<SharedLine>>> slots_;  // key -> unsent events, oldest first
  std::size_t pending_events_ = 0;
  std::uint64_t replaced_ = 0;
};

}  // namespace v4r::server
