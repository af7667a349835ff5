// v4r - robust model-based object tracking. MIT licence.
#include "v4r/server/client.hpp"

#include <istream>
#include <optional>

#include <asio.hpp>
#include <fmt/format.h>

namespace v4r::server {

namespace {
constexpr std::size_t kClientMaxLine = 1u << 20;  // bytes: longest line a Client accepts
}

/// Asio state of one connection; every operation is asynchronous and driven by run_for() so
/// that each call has a timeout.
struct Client::Impl {
  asio::io_context io;
  asio::ip::tcp::socket socket{io};
  asio::streambuf in{kClientMaxLine};
  std::string where;

  /// Runs the io_context until `done` or the timeout; on timeout cancels and drains the
  /// operation. Returns false on timeout.
  bool run(const bool& done, Duration timeout) {
    io.restart();
    io.run_for(timeout);
    if (done) return true;
    asio::error_code ignored;
    socket.cancel(ignored);
    io.restart();
    io.run();
    return false;
  }
};

Client::Client() = default;
Client::~Client() { close(); }
Client::Client(Client&&) noexcept = default;
Client& Client::operator=(Client&&) noexcept = default;

bool Client::is_open() const { return impl_ && impl_->socket.is_open(); }

Expected<Client> Client::connect(const std::string& host, std::uint16_t port, Duration timeout) {
  Client c;
  c.impl_ = std::make_unique<Impl>();
  Impl& im = *c.impl_;
  im.where = fmt::format("{}:{}", host, port);
  asio::error_code ec;
  asio::ip::tcp::resolver resolver(im.io);
  const auto endpoints = resolver.resolve(host, std::to_string(port), ec);
  if (ec) return make_error(im.where, 0, 0, "cannot resolve: " + ec.message());
  bool done = false;
  asio::async_connect(im.socket, endpoints, [&](const asio::error_code& e, const asio::ip::tcp::endpoint&) {
    ec = e;
    done = true;
  });
  if (!im.run(done, timeout)) return make_error(im.where, 0, 0, "connection timed out");
  if (ec) return make_error(im.where, 0, 0, "cannot connect: " + ec.message());
  im.socket.set_option(asio::ip::tcp::no_delay(true), ec);
  auto hello = c.read_line(timeout);
  if (!hello) return hello.error();
  c.greeting_ = std::move(*hello);
  return c;
}

Expected<void> Client::send_raw(std::string_view bytes, Duration timeout) {
  if (!is_open()) return make_error("client: not connected");
  Impl& im = *impl_;
  bool done = false;
  asio::error_code ec;
  asio::async_write(im.socket, asio::buffer(bytes.data(), bytes.size()), [&](const asio::error_code& e, std::size_t) {
    ec = e;
    done = true;
  });
  if (!im.run(done, timeout)) return make_error(im.where, 0, 0, "send timed out");
  if (ec) return make_error(im.where, 0, 0, "send failed: " + ec.message());
  return {};
}

Expected<void> Client::send_line(std::string_view line, Duration timeout) {
  std::string s;
  s.reserve(line.size() + 1);
  s.append(line);
  s.push_back('\n');
  return send_raw(s, timeout);
}

Expected<std::string> Client::read_line(Duration timeout) {
  if (!is_open()) return make_error("client: not connected");
  Impl& im = *impl_;
  bool done = false;
  asio::error_code ec;
  std::size_t n = 0;
  asio::async_read_until(im.socket, im.in, '\n', [&](const asio::error_code& e, std::size_t k) {
    ec = e;
    n = k;
    done = true;
  });
  if (!im.run(done, timeout)) return make_error(im.where, 0, 0, "timed out waiting for a line");
  if (ec) {
    if (ec == asio::error::eof) return make_error(im.where, 0, 0, "connection closed by the server");
    if (ec == asio::error::not_found) return make_error(im.where, 0, 0, "line too long");
    return make_error(im.where, 0, 0, "receive failed: " + ec.message());
  }
  std::string line(n, '\0');
  std::istream is(&im.in);
  is.read(line.data(), static_cast<std::streamsize>(n));
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
  return line;
}

bool Client::is_reply(std::string_view line) {
  return line == "OK" || line == "ERR" || line.starts_with("OK ") || line.starts_with("ERR ");
}

Expected<std::string> Client::wait_reply(std::string_view line, Duration timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const auto left = std::chrono::duration_cast<Duration>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return make_error(impl_->where, 0, 0, fmt::format("no reply to '{}'", line.substr(0, 60)));
    auto l = read_line(left);
    if (!l) return l.error();
    if (is_reply(*l)) return l;
    events_.push_back(std::move(*l));
  }
}

Expected<std::string> Client::request(std::string_view line, Duration timeout) {
  auto s = send_line(line, timeout);
  if (!s) return s.error();
  return wait_reply(line, timeout);
}

Expected<std::string> Client::request_with_payload(std::string_view line, std::string_view payload, Duration timeout) {
  std::string s;
  s.reserve(line.size() + 1 + payload.size());
  s.append(line);
  s.push_back('\n');
  s.append(payload);
  auto r = send_raw(s, timeout);
  if (!r) return r.error();
  return wait_reply(line, timeout);
}

Expected<std::string> Client::next_event(Duration timeout) {
  if (!events_.empty()) {
    std::string e = std::move(events_.front());
    events_.pop_front();
    return e;
  }
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const auto left = std::chrono::duration_cast<Duration>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return make_error(impl_ ? impl_->where : std::string(), 0, 0, "timed out waiting for an event");
    auto l = read_line(left);
    if (!l) return l.error();
    if (!is_reply(*l)) return l;
  }
}

void Client::close() {
  if (!impl_) return;
  asio::error_code ignored;
  if (impl_->socket.is_open()) {
    impl_->socket.shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
    impl_->socket.close(ignored);
  }
}

}  // namespace v4r::server
