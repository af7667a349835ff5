// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <string_view>

#include "v4r/core/expected.hpp"

namespace v4r::server {

/// \brief A blocking client of the v4r ASCII protocol over one TCP connection, with a timeout on
/// every call: send command lines (and payloads), wait for their replies, read event lines.
/// Lines are returned without their line end. Not thread-safe: one thread per Client.
///
/// \code
///   auto c = Client::connect("127.0.0.1", 5757);
///   c->request("AddObject name=box");
///   c->request_with_payload("AddModel object=box format=cao bytes=" + std::to_string(cao.size()), cao);
///   c->request("SetPose object=box t=0,0,0.6 r=0,0,0");
///   c->request("Subscribe what=ObjectPose");
///   while (auto ev = c->next_event(std::chrono::seconds(1))) use(*ev);
/// \endcode
class Client {
 public:
  using Duration = std::chrono::milliseconds;
  static constexpr Duration kDefaultTimeout{5000};

  Client();
  ~Client();
  Client(Client&&) noexcept;
  Client& operator=(Client&&) noexcept;

  /// Connects to host:port (numeric address or name) and reads the greeting line
  /// (`Hello version=1`). Errors name the address.
  static Expected<Client> connect(const std::string& host, std::uint16_t port, Duration timeout = kDefaultTimeout);

  /// The greeting line the server sent.
  [[nodiscard]] const std::string& greeting() const { return greeting_; }
  [[nodiscard]] bool is_open() const;

  /// Sends `line` followed by LF.
  Expected<void> send_line(std::string_view line, Duration timeout = kDefaultTimeout);
  /// Sends bytes as they are (payloads, or deliberately broken input in tests).
  Expected<void> send_raw(std::string_view bytes, Duration timeout = kDefaultTimeout);

  /// The next line from the server, whatever it is. Error on timeout (the connection stays
  /// usable), when the server closed the connection, or when a line exceeds 1 MiB.
  Expected<std::string> read_line(Duration timeout = kDefaultTimeout);

  /// Sends a command line and returns its reply (`OK <Command> ...` or `ERR <Command> ...`: an
  /// ERR reply is a value, not an Error). Event lines that arrive meanwhile are kept for next_event().
  Expected<std::string> request(std::string_view line, Duration timeout = kDefaultTimeout);
  /// Sends a command line announcing a payload (`AddModel ... bytes=N`), then the N bytes, and
  /// returns the reply.
  Expected<std::string> request_with_payload(std::string_view line, std::string_view payload,
                                             Duration timeout = kDefaultTimeout);
  /// The next event line (anything that is not a reply): first those kept by request().
  Expected<std::string> next_event(Duration timeout = kDefaultTimeout);

  /// Closes the connection (also done by the destructor).
  void close();

  /// True for `OK ...` and `ERR ...` lines.
  static bool is_reply(std::string_view line);

 private:
  Expected<std::string> wait_reply(std::string_view line, Duration timeout);
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string greeting_;
  std::deque<std::string> events_;
};

}  // namespace v4r::server
