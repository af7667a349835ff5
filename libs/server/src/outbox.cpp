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
    if (slot.size() >= event_depth_) {
      slot.pop_front();
      ++replaced_;
    } else {
      ++pending_events_;
    }
    slot.push_back(std::move(line));
    return;
  }
  slots_.emplace_back(key, std::deque<SharedLine>{});
  slots_.back().second.push_back(std::move(line));
  ++pending_events_;
}

void Outbox::drop_events(const std::string& prefix) {
  for (auto& [k, slot] : slots_) {
    if (!slot.empty() && k.starts_with(prefix)) {
      pending_events_ -= slot.size();
      slot.clear();
    }
  }
}

std::size_t Outbox::take(std::vector<SharedLine>& out) {
  const std::size_t n0 = out.size();
  while (!replies_.empty()) {
    out.push_back(std::move(replies_.front()));
    replies_.pop_front();
  }
  for (std::size_t round = 0;; ++round) {
    bool any = false;
    for (auto& [k, slot] : slots_) {
      if (round >= slot.size()) continue;
      out.push_back(std::move(slot[round]));
      any = true;
    }
    if (!any) break;
  }
  for (auto& [k, slot] : slots_) slot.clear();
  pending_events_ = 0;
  // Keys of removed objects would pile up: keep the slot table small.
  if (slots_.size() > 64) slots_.clear();
  return out.size() - n0;
}

}  // namespace v4r::server
