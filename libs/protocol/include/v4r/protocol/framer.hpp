// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <variant>

#include "v4r/protocol/protocol.hpp"

namespace v4r::protocol {

/// \brief Splits the bytes received on one connection into protocol lines and AddModel payloads.
/// Pure: bytes in, frames out. The socket code calls feed() after each read, then next() until it
/// returns nothing; between reads it then holds at most kMaxLineBytes + 1 bytes of an unfinished
/// line, however long the line really is (or the part of a payload received so far).
class Framer {
 public:
  /// \brief A complete line, without its LF and without one trailing CR.
  struct Line {
    std::string text;
  };
  /// \brief A line longer than the limit: reported once, as soon as it is seen, with the ERR to send
  /// (code too_long); the rest of it, through the next LF, is dropped.
  struct Overlong {
    ParseError error;
  };
  /// \brief The bytes asked for with expect_payload(n, true), all n of them.
  struct Payload {
    std::string bytes;
  };
  using Frame = std::variant<Line, Overlong, Payload>;

  explicit Framer(std::size_t max_line_bytes = kMaxLineBytes) : max_line_(max_line_bytes) {}

  /// Appends received bytes.
  void feed(std::string_view data);
  /// The next complete frame, or nothing until more bytes are fed.
  std::optional<Frame> next();
  /// The n bytes that follow the last line returned are a payload (an AddModel model): returned
  /// as one Payload when keep, else dropped (ParseError::skip_bytes). Call right after next()
  /// returned the line; replaces any payload still pending.
  void expect_payload(std::size_t n, bool keep = true);

  /// Payload bytes still to come; > 0 at a disconnect means the payload was cut off.
  [[nodiscard]] std::size_t payload_remaining() const { return payload_left_; }
  /// Bytes held: an unfinished line or payload (at most the line limit, or the payload size).
  [[nodiscard]] std::size_t buffered() const { return buf_.size() - pos_ + payload_.size(); }

 private:
  std::size_t max_line_;
  std::string buf_;
  std::size_t pos_ = 0;   ///< first byte not consumed
  std::size_t scan_ = 0;  ///< bytes before this index (>= pos_) hold no LF
  bool discarding_ = false;
  std::size_t payload_left_ = 0;
  bool payload_keep_ = false;
  std::string payload_;
};

}  // namespace v4r::protocol
