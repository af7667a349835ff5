// v4r - robust model-based object tracking. MIT licence.
#include "v4r/server/outbox.hpp"

namespace v4r::server {

bool Outbox::push_reply(SharedLine line) {
  if (replies_.size() >= max_replies_) return false;
  replies_.push_back(std::move(line));
  return true;
}

void Outbox::put_event(const std::string& key, SharedLine line) {
  for (auto& [k, slot] : slots_) {
    if (k != key) continue;
    if (slot) {
      ++replaced_;
    } else {
      ++pending_events_;
    }
    slot = std::move(line);
    return;
  }
  slots_.emplace_back(key, std::move(line));
  ++pending_events_;
}

void Outbox::drop_events(const std::string& prefix) {
  for (auto& [k, slot] : slots_) {
    if (slot && k.starts_with(prefix)) {
      slot.reset();
      --pending_events_;
    }
  }
}

std::size_t Outbox::take(std::vector<SharedLine>& out) {
  const std::size_t n0 = out.size();
  while (!replies_.empty()) {
    out.push_back(std::move(replies_.front()));
    replies_.pop_front();
  }
  for (auto& [k, slot] : slots_) {
    if (slot) out.push_back(std::move(slot));
    slot.reset();
  }
  pending_events_ = 0;
  // Keys of removed objects would pile up: keep the slot table small.
  if (slots_.size() > 64) slots_.clear();
  return out.size() - n0;
}

}  // namespace v4r::server
