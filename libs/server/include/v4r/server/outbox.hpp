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
/// in order) and one "latest event" slot per event key (an object's ObjectPose, the
/// SystemStatus): a newer event replaces an unsent older one, so a slow client gets the newest
/// state instead of a growing queue. Memory is bounded by max_replies plus the number of keys.
/// Not thread-safe (owned by the thread that writes to the client).
class Outbox {
 public:
  explicit Outbox(std::size_t max_replies = 256) : max_replies_(max_replies) {}

  /// Queues a reply. Returns false (and drops the reply) when max_replies are already waiting:
  /// the client does not read and is to be disconnected.
  bool push_reply(SharedLine line);
  /// Stores the newest event under `key` (e.g. "P box", "S"), replacing an unsent one.
  void put_event(const std::string& key, SharedLine line);
  /// Forgets unsent events whose key starts with `prefix` (after an Unsubscribe).
  void drop_events(const std::string& prefix);

  [[nodiscard]] bool empty() const { return replies_.empty() && pending_events_ == 0; }
  [[nodiscard]] std::size_t replies_waiting() const { return replies_.size(); }
  /// Events replaced before they were sent (a measure of how slow the client is).
  [[nodiscard]] std::uint64_t events_replaced() const { return replaced_; }

  /// Moves everything waiting into `out` in sending order: replies first, then the events in the
  /// order their keys first appeared. Returns the number of lines appended.
  std::size_t take(std::vector<SharedLine>& out);

 private:
  std::size_t max_replies_;
  std::deque<SharedLine> replies_;
  std::vector<std::pair<std::string, SharedLine>> slots_;  // key -> newest unsent event (null: none)
  std::size_t pending_events_ = 0;
  std::uint64_t replaced_ = 0;
};

}  // namespace v4r::server
