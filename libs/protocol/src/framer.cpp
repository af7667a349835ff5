// v4r - robust model-based object tracking. MIT licence.
#include "v4r/protocol/framer.hpp"

#include <algorithm>

#include "lexer.hpp"

namespace v4r::protocol {
namespace {

Framer::Overlong overlong(std::string_view head, std::size_t max_line) {
  ParseError e;
  e.command = detail::command_word(head.substr(0, std::min<std::size_t>(head.size(), 80)));
  e.code = std::string(code::kTooLong);
  e.message = "line longer than the limit of " + std::to_string(max_line) + " bytes; dropped through the next LF";
  return Framer::Overlong{std::move(e)};
}

}  // namespace

void Framer::feed(std::string_view data) {
  if (pos_ > 0) {
    buf_.erase(0, pos_);
    scan_ -= pos_;
    pos_ = 0;
  }
  buf_.append(data.data(), data.size());
}

void Framer::expect_payload(std::size_t n, bool keep) {
  payload_left_ = n;
  payload_keep_ = keep;
  payload_.clear();
}

std::optional<Framer::Frame> Framer::next() {
  for (;;) {
    if (payload_left_ > 0) {
      const std::size_t take = std::min(payload_left_, buf_.size() - pos_);
      if (payload_keep_) payload_.append(buf_, pos_, take);
      pos_ += take;
      scan_ = std::max(scan_, pos_);
      payload_left_ -= take;
      if (payload_left_ > 0) return std::nullopt;
      if (payload_keep_) {
        Payload p{std::move(payload_)};
        payload_.clear();
        return p;
      }
      continue;
    }
    const std::size_t from = std::max(scan_, pos_);
    const std::size_t lf = buf_.find('\n', from);
    if (discarding_) {
      if (lf == std::string::npos) {
        pos_ = scan_ = buf_.size();
        return std::nullopt;
      }
      pos_ = scan_ = lf + 1;
      discarding_ = false;
      continue;
    }
    if (lf != std::string::npos) {
      std::string_view line(buf_.data() + pos_, lf - pos_);
      pos_ = scan_ = lf + 1;
      line = detail::strip_cr(line);
      if (line.size() > max_line_) return overlong(line, max_line_);
      return Line{std::string(line)};
    }
    scan_ = buf_.size();
    // Without its LF a line may still end in CR, hence the + 1.
    if (buf_.size() - pos_ > max_line_ + 1) {
      Overlong o = overlong(std::string_view(buf_).substr(pos_), max_line_);
      pos_ = scan_ = buf_.size();
      discarding_ = true;
      return o;
    }
    return std::nullopt;
  }
}

}  // namespace v4r::protocol
