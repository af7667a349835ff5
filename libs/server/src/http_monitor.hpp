// v4r - robust model-based object tracking. MIT licence.
#pragma once

// Internal: the HTTP monitoring page of `v4r serve --http PORT`.

#include <cstdint>
#include <functional>
#include <memory>
#include <set>
#include <string>
#include <string_view>

#include <asio.hpp>

#include "v4r/server/outbox.hpp"

namespace v4r::server {

class HttpConnection;

/// \brief A minimal HTTP/1.0 server on the network thread for watching the tracker: `/` (an HTML
/// page), `/stream.mjpg` (the overlay images as multipart/x-mixed-replace JPEGs, newest image
/// per viewer, none while `Display off`) and `/status.json` (the latest SystemStatus and poses).
/// GET only; request heads are limited to 8 KiB and 10 s; at most kMaxViewers connections. With
/// a token, every request must carry it as a query parameter (`/?token=SECRET`), else 401.
class HttpMonitor {
 public:
  static constexpr std::size_t kMaxViewers = 32;

  /// `status_json` is called on the network thread for each /status.json request.
  HttpMonitor(asio::ip::tcp::acceptor acceptor, std::function<std::string()> status_json, std::string token = {});
  ~HttpMonitor();

  void start();
  void stop();
  [[nodiscard]] std::uint16_t port() const { return port_; }
  /// A new overlay JPEG for every stream viewer (network thread).
  void publish_jpeg(SharedLine jpeg);

  // Used by the connections.
  [[nodiscard]] const SharedLine& latest_jpeg() const { return latest_; }
  [[nodiscard]] std::string status_json() const { return status_json_(); }
  /// True when the request's query string carries the token (or none is required).
  [[nodiscard]] bool authorised(std::string_view query) const;
  void add_viewer(const std::shared_ptr<HttpConnection>& c) { viewers_.insert(c); }
  void remove(const std::shared_ptr<HttpConnection>& c);

 private:
  void accept();

  asio::ip::tcp::acceptor acceptor_;
  std::function<std::string()> status_json_;
  std::string token_;
  std::uint16_t port_ = 0;
  SharedLine latest_;
  std::set<std::shared_ptr<HttpConnection>> connections_, viewers_;
  bool stopped_ = false;
};

}  // namespace v4r::server
