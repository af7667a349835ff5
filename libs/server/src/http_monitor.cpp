// v4r - robust model-based object tracking. MIT licence.
#include "http_monitor.hpp"

#include <array>
#include <algorithm>
#include <chrono>
#include <istream>

#include <fmt/format.h>

#include "v4r/server/http_request.hpp"

namespace v4r::server {

namespace {

constexpr std::chrono::seconds kHeadTimeout{10};
constexpr std::chrono::seconds kWriteTimeout{10};
constexpr std::chrono::milliseconds kRepeatInterval{500};
constexpr const char* kBoundary = "v4rframe";

constexpr const char* kPage = R"(<!doctype html>
<html><head><meta charset="utf-8"><title>v4r serve</title>
<style>body{font-family:sans-serif;background:#222;color:#ddd;margin:1em}
img{max-width:100%;border:1px solid #555;background:#000;min-width:320px;min-height:240px}
table{border-collapse:collapse}td,th{padding:2px 10px;text-align:right}th{text-align:left}</style></head>
<body><h1>v4r serve</h1>
<p>Camera image with the projected model (send <code>Display on</code> to a server connection to see it).</p>
<img id="stream" alt="overlay stream">
<h2>SystemStatus</h2><table id="status"></table>
<h2>Objects</h2><table id="objects"></table>
<script>
const q=location.search;  // carries ?token=... when the server wants one
document.getElementById('stream').src='/stream.mjpg'+q;
async function poll(){
  try{
    const s=await (await fetch('/status.json'+q,{cache:'no-store'})).json();
    const rows=['frame','cycle_ms','features_found','features_used','outliers','overruns','clients','paused','end_of_input','display'];
    document.getElementById('status').innerHTML=rows.map(k=>`<tr><th>${k}</th><td>${s[k]}</td></tr>`).join('');
    document.getElementById('objects').innerHTML='<tr><th>object</th><th>status</th><th>quality</th><th>t (m)</th></tr>'+
      s.objects.map(o=>`<tr><th>${o.object}</th><td>${o.status}</td><td>${o.quality.toFixed(2)}</td><td>${o.t.map(x=>x.toFixed(4)).join(', ')}</td></tr>`).join('');
  }catch(e){}
  setTimeout(poll,500);
}
poll();
</script></body></html>
)";

}  // namespace

/// \brief One HTTP connection: reads the request head, answers it, and for /stream.mjpg keeps
/// sending the newest JPEG whenever the previous one has been written.
class HttpConnection : public std::enable_shared_from_this<HttpConnection> {
 public:
  HttpConnection(asio::ip::tcp::socket s, HttpMonitor& m)
      : socket_(std::move(s)), timer_(socket_.get_executor()), repeat_(socket_.get_executor()), monitor_(m) {}

  void start() {
    arm(kHeadTimeout);
    asio::async_read_until(socket_, head_, "\r\n\r\n", [self = shared_from_this()](const asio::error_code& ec, std::size_t) {
      self->on_head(ec);
    });
  }

  void push(const SharedLine& jpeg) {
    pending_ = jpeg;
    write_frame();
  }

  void close() {
    if (closed_) return;
    closed_ = true;
    asio::error_code ignored;
    socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
    socket_.close(ignored);
    timer_.cancel();
    repeat_.cancel();
    monitor_.remove(shared_from_this());
  }

 private:
  void arm(std::chrono::seconds d) {
    timer_.expires_after(d);
    timer_.async_wait([w = weak_from_this()](const asio::error_code& ec) {
      if (auto s = w.lock(); s && !ec) s->close();
    });
  }

  void on_head(const asio::error_code& ec) {
    timer_.cancel();
    if (ec || closed_) {
      close();
      return;
    }
    const auto data = head_.data();
    const std::string head(asio::buffers_begin(data), asio::buffers_end(data));
    auto req = parse_http_request(head);
    if (!req) return respond("400 Bad Request", "text/plain", req.error().message + "\n");
    if (req->method != "GET" && req->method != "HEAD")
      return respond("405 Method Not Allowed", "text/plain", "GET only\n");
    const std::string& target = req->path;
    if (!monitor_.authorised(req->query)) return respond("401 Unauthorized", "text/plain", "add ?token=SECRET to the address\n");
    if (target == "/" || target == "/index.html") return respond("200 OK", "text/html; charset=utf-8", kPage);
    if (target == "/status.json") return respond("200 OK", "application/json", monitor_.status_json());
    if (target == "/stream.mjpg") return start_stream();
    respond("404 Not Found", "text/plain", "not found\n");
  }

  void respond(const char* status, const char* type, std::string body) {
    text_ = fmt::format("HTTP/1.0 {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\n"
                        "Connection: close\r\n\r\n{}",
                        status, type, body.size(), body);
    arm(kWriteTimeout);
    asio::async_write(socket_, asio::buffer(text_), [self = shared_from_this()](const asio::error_code&, std::size_t) {
      self->close();
    });
  }

  void start_stream() {
    streaming_ = true;
    text_ = fmt::format("HTTP/1.0 200 OK\r\nContent-Type: multipart/x-mixed-replace; boundary={}\r\n"
                        "Cache-Control: no-store\r\nConnection: close\r\n\r\n--{}\r\n",
                        kBoundary, kBoundary);
    writing_ = true;
    arm(kWriteTimeout);
    asio::async_write(socket_, asio::buffer(text_), [self = shared_from_this()](const asio::error_code& ec, std::size_t) {
      self->on_written(ec);
    });
    monitor_.add_viewer(shared_from_this());
    pending_ = monitor_.latest_jpeg();
  }

  void write_frame() {
    if (!streaming_ || writing_ || closed_ || !pending_) return;
    sending_ = std::move(pending_);
    pending_.reset();
    // Each part ends with the next boundary: a browser shows a part only once it sees the
    // boundary after it, so the newest image must not wait for the next frame.
    part_ = fmt::format("Content-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n", sending_->size());
    tail_ = fmt::format("\r\n--{}\r\n", kBoundary);
    buffers_ = {asio::buffer(part_), asio::buffer(*sending_), asio::buffer(tail_)};
    writing_ = true;
    arm(kWriteTimeout);
    asio::async_write(socket_, buffers_, [self = shared_from_this()](const asio::error_code& ec, std::size_t) {
      self->on_written(ec);
    });
  }

  void on_written(const asio::error_code& ec) {
    writing_ = false;
    timer_.cancel();
    if (ec || closed_) {
      close();
      return;
    }
    write_frame();
    if (!writing_) arm_repeat();
  }

  // Chromium shows a part of a multipart stream only when the next part begins, so the newest
  // image is repeated while no new one comes (paused or ended input, Display off): a still scene
  // is shown too, and an idle viewer's connection stays alive.
  void arm_repeat() {
    repeat_.expires_after(kRepeatInterval);
    repeat_.async_wait([w = weak_from_this()](const asio::error_code& ec) {
      auto s = w.lock();
      if (!s || ec || s->closed_ || s->writing_) return;
      if (!s->pending_) s->pending_ = s->monitor_.latest_jpeg();
      s->write_frame();
    });
  }

  asio::ip::tcp::socket socket_;
  asio::steady_timer timer_;   // deadline of the current read or write
  asio::steady_timer repeat_;  // repeats the newest image while no new one comes
  HttpMonitor& monitor_;
  asio::streambuf head_{kMaxHttpHeadBytes};
  std::string text_, part_, tail_;
  std::array<asio::const_buffer, 3> buffers_;
  SharedLine pending_, sending_;
  bool streaming_ = false, writing_ = false, closed_ = false;
};

HttpMonitor::HttpMonitor(asio::ip::tcp::acceptor acceptor, std::function<std::string()> status_json, std::string token)
    : acceptor_(std::move(acceptor)), status_json_(std::move(status_json)), token_(std::move(token)) {
  asio::error_code ec;
  port_ = acceptor_.local_endpoint(ec).port();
}

HttpMonitor::~HttpMonitor() = default;

void HttpMonitor::start() { accept(); }

bool HttpMonitor::authorised(std::string_view query) const {
  return query_has_token(query, token_);
}

void HttpMonitor::stop() {
  stopped_ = true;
  asio::error_code ignored;
  acceptor_.close(ignored);
  auto all = connections_;
  for (const auto& c : all) c->close();
  connections_.clear();
  viewers_.clear();
}

void HttpMonitor::remove(const std::shared_ptr<HttpConnection>& c) {
  connections_.erase(c);
  viewers_.erase(c);
}

void HttpMonitor::publish_jpeg(SharedLine jpeg) {
  latest_ = std::move(jpeg);
  auto viewers = viewers_;
  for (const auto& v : viewers) v->push(latest_);
}

void HttpMonitor::accept() {
  acceptor_.async_accept([this](const asio::error_code& ec, asio::ip::tcp::socket s) {
    if (stopped_ || !acceptor_.is_open()) return;
    if (!ec) {
      if (connections_.size() >= kMaxViewers) {
        asio::error_code ignored;
        s.close(ignored);
      } else {
        auto c = std::make_shared<HttpConnection>(std::move(s), *this);
        connections_.insert(c);
        c->start();
      }
    }
    accept();
  });
}

}  // namespace v4r::server
