// v4r - robust model-based object tracking. MIT licence.
#include "v4r/server/server.hpp"

#include <atomic>
#include <csignal>
#include <mutex>
#include <set>
#include <thread>

#include <asio.hpp>
#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "http_monitor.hpp"
#include "session.hpp"
#include "v4r/core/log.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/server/model_loading.hpp"
#include "v4r/server/tracking_service.hpp"

namespace v4r::server {

namespace {

constexpr std::size_t kMaxReleaseTimes = 1'000'000;  // frames whose release time is kept (8 MB)
constexpr int kJpegQuality = 80;
constexpr std::size_t kMaxPayloadsInFlight = std::size_t{64} << 20;  // bytes of inline models held at once

std::string json_number(double x) { return std::isfinite(x) ? protocol::format_number(x) : std::string("null"); }

/// JSON string literal for names (protocol names are [A-Za-z0-9_.-], but stay safe).
std::string json_string(std::string_view s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out.push_back('\\');
      out.push_back(c);
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += fmt::format("\\u{:04x}", static_cast<unsigned>(c));
    } else {
      out.push_back(c);
    }
  }
  return out + "\"";
}

Expected<asio::ip::tcp::acceptor> listen(asio::io_context& io, const asio::ip::address& addr, std::uint16_t port) {
  asio::error_code ec;
  asio::ip::tcp::acceptor a(io);
  const asio::ip::tcp::endpoint ep(addr, port);
  a.open(ep.protocol(), ec);
  if (!ec) a.set_option(asio::ip::tcp::acceptor::reuse_address(true), ec);
  if (!ec) a.bind(ep, ec);
  if (!ec) a.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) return make_error(fmt::format("cannot listen on {}:{}: {}", addr.to_string(), port, ec.message()));
  return a;
}

}  // namespace

struct Server::Impl final : SessionHost {
  // The io_context is declared first so that it is destroyed last (handlers own sessions).
  asio::io_context io_{1};
  ServerOptions opt_;
  PathPolicy data_dirs_;
  asio::ip::tcp::acceptor acceptor_{io_};
  asio::steady_timer accept_retry_{io_};
  asio::signal_set signals_{io_};
  std::unique_ptr<HttpMonitor> http_;
  std::unique_ptr<TrackingService> service_;
  Worker loader_, encoder_;
  std::set<std::shared_ptr<Session>> sessions_;   // network thread only
  std::shared_ptr<const FrameEvents> last_frame_;  // network thread only
  std::uint16_t port_ = 0;

  mutable std::mutex release_mutex_;
  std::vector<Clock::time_point> released_;
  std::mutex overlay_mutex_;
  std::shared_ptr<const cv::Mat> overlay_;
  bool encoding_ = false;

  std::atomic<std::size_t> clients_{0};
  std::atomic<std::uint64_t> connections_{0}, refused_{0}, slow_{0}, net_faults_{0}, observer_faults_{0};
  std::atomic<std::size_t> peak_lines_{0}, peak_bytes_{0};
  std::atomic<bool> stopping_{false};
  std::atomic<std::size_t> payload_bytes_{0};
  bool shut_down_ = false;  // network thread
  std::jthread io_thread_;

  ~Impl() override {
    if (service_) service_->stop();
    loader_.stop();
    encoder_.stop();
  }

  asio::io_context& io() override { return io_; }
  TrackingService& service() override { return *service_; }
  Worker& loader() override { return loader_; }
  const ServerOptions& options() const override { return opt_; }
  const PathPolicy& data_dirs() const override { return data_dirs_; }

  void dropping_slow_client() override { ++slow_; }
  void note_write(std::size_t lines, std::size_t bytes) override {
    // Network thread only: plain max.
    if (lines > peak_lines_) peak_lines_ = lines;
    if (bytes > peak_bytes_) peak_bytes_ = bytes;
  }

  void session_closed(const std::shared_ptr<Session>& s) override {
    // Deferred: the session may be closing from inside a loop over sessions_.
    asio::post(io_, [this, s] {
      sessions_.erase(s);
      clients_ = sessions_.size();
    });
  }

  bool reserve_payload(std::size_t bytes) override {
    std::size_t cur = payload_bytes_.load();
    do {
      if (cur + bytes > kMaxPayloadsInFlight) return false;
    } while (!payload_bytes_.compare_exchange_weak(cur, cur + bytes));
    return true;
  }
  void release_payload(std::size_t bytes) override { payload_bytes_ -= bytes; }

  void accept() {
    acceptor_.async_accept([this](const asio::error_code& ec, asio::ip::tcp::socket socket) {
      if (shut_down_ || !acceptor_.is_open()) return;
      if (ec) {
        // Out of descriptors or similar: try again a little later instead of spinning.
        accept_retry_.expires_after(std::chrono::milliseconds(100));
        accept_retry_.async_wait([this](const asio::error_code& e) {
          if (!e) accept();
        });
        return;
      }
      ++connections_;
      auto s = std::make_shared<Session>(std::move(socket), *this);
      if (sessions_.size() >= opt_.max_clients) {
        ++refused_;
        s->refuse(fmt::format("too many clients (at most {})", opt_.max_clients));
      } else {
        sessions_.insert(s);
        clients_ = sessions_.size();
        s->start();
      }
      accept();
    });
  }

  /// Tracking thread: hands the frame's events to the network thread.
  void on_frame(std::shared_ptr<const FrameEvents> ev) {
    if (opt_.frame_observer) {
      try {
        opt_.frame_observer(*ev);
      } catch (const std::exception& e) {
        ++observer_faults_;
        V4R_LOG_ERROR("v4r serve: frame observer failed: {}", e.what());
      }
    }
    {
      std::scoped_lock lock(release_mutex_);
      if (released_.size() < kMaxReleaseTimes) released_.push_back(ev->released);
    }
    asio::post(io_, [this, ev = std::move(ev)] {
      last_frame_ = ev;
      for (const auto& s : sessions_) s->deliver(*ev);
    });
  }

  /// Tracking thread: the newest overlay goes to the JPEG encoder (older unencoded ones are dropped).
  void on_overlay(std::shared_ptr<const cv::Mat> img) {
    std::scoped_lock lock(overlay_mutex_);
    overlay_ = std::move(img);
    if (encoding_) return;
    encoding_ = true;
    encoder_.post([this] { encode_overlays(); });
  }

  void encode_overlays() {
    for (;;) {
      std::shared_ptr<const cv::Mat> img;
      {
        std::scoped_lock lock(overlay_mutex_);
        img = std::move(overlay_);
        overlay_.reset();
        if (!img) {
          encoding_ = false;
          return;
        }
      }
      std::vector<uchar> buf;
      try {
        if (!cv::imencode(".jpg", *img, buf, {cv::IMWRITE_JPEG_QUALITY, kJpegQuality})) continue;
      } catch (const std::exception& e) {  // an OpenCV error costs this picture only
        V4R_LOG_ERROR("v4r serve: monitor picture not encoded: {}", e.what());
        continue;
      }
      auto jpeg = std::make_shared<const std::string>(buf.begin(), buf.end());
      asio::post(io_, [this, jpeg = std::move(jpeg)] {
        if (http_ && !shut_down_) http_->publish_jpeg(jpeg);
      });
    }
  }

  std::string status_json() const {
    std::string s = "{";
    const FrameEvents* f = last_frame_.get();
    s += fmt::format("\"frame\":{},", f ? std::to_string(f->frame) : "null");
    s += fmt::format("\"stamp\":{},", f ? json_number(f->stamp_s) : "null");
    s += fmt::format("\"cycle_ms\":{},", f ? json_number(f->status.cycle_ms) : "null");
    s += fmt::format("\"features_found\":{},\"features_used\":{},\"outliers\":{},\"overruns\":{},",
                     f ? f->status.features_found : 0, f ? f->status.features_used : 0, f ? f->status.outliers : 0,
                     f ? f->status.overruns : 0);
    s += fmt::format("\"clients\":{},\"paused\":{},\"end_of_input\":{},\"display\":{},", clients_.load(),
                     service_->paused(), service_->end_of_input(), service_->display());
    s += "\"objects\":[";
    if (f) {
      for (std::size_t i = 0; i < f->poses.size(); ++i) {
        const protocol::ObjectPoseEvent& p = f->poses[i];
        if (i) s += ",";
        s += fmt::format("{{\"object\":{},\"status\":\"{}\",\"quality\":{},\"t\":[{},{},{}],\"q\":[{},{},{},{}]}}",
                         json_string(p.object), protocol::to_string(p.status), json_number(p.quality),
                         json_number(p.t[0]), json_number(p.t[1]), json_number(p.t[2]), json_number(p.q[0]),
                         json_number(p.q[1]), json_number(p.q[2]), json_number(p.q[3]));
      }
    }
    s += "]}";
    return s;
  }

  void begin() {
    service_->start();
    accept();
    if (http_) http_->start();
    if (opt_.handle_signals) {
      signals_.add(SIGINT);
      signals_.add(SIGTERM);
      signals_.async_wait([this](const asio::error_code& ec, int sig) {
        if (ec) return;
        V4R_LOG_INFO("v4r serve: signal {}, shutting down", sig);
        shutdown();
      });
    }
  }

  /// The network thread. A handler that throws (a bug, out of memory) is logged and the loop goes
  /// on: one client's request must not end every client's session. Only the shutdown itself
  /// failing ends the thread, logged.
  void serve() {
    for (;;) {
      try {
        io_.run();
        break;
      } catch (const std::exception& e) {
        const std::uint64_t n = ++net_faults_;
        if (n <= 10 || n % 1000 == 0) V4R_LOG_ERROR("v4r serve: network handler failed: {}", e.what());
      } catch (...) {
        const std::uint64_t n = ++net_faults_;
        if (n <= 10 || n % 1000 == 0) V4R_LOG_ERROR("v4r serve: network handler failed: unknown exception");
      }
    }
    try {
      shutdown();
    } catch (const std::exception& e) {
      V4R_LOG_ERROR("v4r serve: shutdown: {}", e.what());
    }
  }

  /// Network thread: closes the ports and every connection, stops the other threads.
  void shutdown() {
    if (shut_down_) return;
    shut_down_ = true;
    asio::error_code ignored;
    acceptor_.close(ignored);
    accept_retry_.cancel();
    signals_.cancel(ignored);
    if (http_) http_->stop();
    auto all = sessions_;
    for (const auto& s : all) s->close();
    sessions_.clear();
    clients_ = 0;
    service_->stop();
    loader_.stop();
    encoder_.stop();
    io_.stop();
  }
};

Server::Server(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Server::~Server() { stop(); }

Expected<std::unique_ptr<Server>> Server::create(ServerOptions opt) {
  auto source = io::FrameSource::open(opt.input);
  if (!source) return source.error();
  ServeScene one;
  one.cameras.push_back(scene::Camera{"camera", opt.camera, geometry::SE3()});
  one.inputs.push_back(std::move(*source));
  return create(std::move(opt), std::move(one));
}

Expected<std::unique_ptr<Server>> Server::create(ServerOptions opt, ServeScene scene) {
  if (!std::isfinite(opt.fps) || opt.fps < 0.0) return make_error("--fps must be >= 0");
  if (opt.max_clients == 0) return make_error("--max-clients must be > 0");
  std::string bind = opt.bind == "localhost" ? std::string("127.0.0.1") : opt.bind;
  asio::error_code ec;
  const asio::ip::address addr = asio::ip::make_address(bind, ec);
  if (ec) return make_error(fmt::format("--bind {}: not an IP address", opt.bind));
  if (!addr.is_loopback() && opt.token.empty())
    return make_error(fmt::format("--bind {}: listening beyond loopback requires --token SECRET", opt.bind));

  auto data = PathPolicy::create(opt.data_dirs.empty() ? std::vector<std::string>{"."} : opt.data_dirs, "--data-dir");
  if (!data) return data.error();
  PathPolicy logs;
  if (!opt.log_dir.empty()) {
    auto l = PathPolicy::create({opt.log_dir}, "--log-dir");
    if (!l) return l.error();
    logs = std::move(*l);
  }

  if (scene.cameras.empty() || scene.inputs.size() != scene.cameras.size())
    return make_error("the scene needs one input per camera");
  auto impl = std::make_unique<Impl>();
  impl->opt_ = opt;
  impl->data_dirs_ = std::move(*data);
  ServiceOptions so;
  so.camera = opt.camera;
  so.fps = opt.fps;
  so.paused = opt.paused;
  so.params = opt.params;
  so.search = opt.search;
  so.detect = opt.detect;
  so.cache_dir = opt.cache_dir;
  so.default_log_file = opt.log_file;
  so.log_dirs = std::move(logs);
  so.object_hook = opt.object_hook;
  so.camera = scene.cameras[0].intrinsics;
  so.cameras = std::move(scene.cameras);
  so.reference_frame = std::move(scene.reference_frame);
  so.objects = std::move(scene.objects);
  impl->service_ = std::make_unique<TrackingService>(std::move(so), std::move(scene.inputs));
  if (auto r = impl->service_->open(); !r) return r.error();

  auto acceptor = listen(impl->io_, addr, opt.port);
  if (!acceptor) return acceptor.error();
  impl->acceptor_ = std::move(*acceptor);
  impl->port_ = impl->acceptor_.local_endpoint(ec).port();
  if (opt.http_port >= 0) {
    if (opt.http_port > 65535) return make_error("--http: not a port number");
    auto http = listen(impl->io_, addr, static_cast<std::uint16_t>(opt.http_port));
    if (!http) return http.error();
    Impl* p = impl.get();
    impl->http_ = std::make_unique<HttpMonitor>(std::move(*http), [p] { return p->status_json(); }, opt.token);
    impl->service_->set_overlay_callback(
        [p](std::shared_ptr<const cv::Mat> img, std::int64_t) { p->on_overlay(std::move(img)); });
  }
  Impl* p = impl.get();
  impl->service_->set_frame_callback([p](std::shared_ptr<const FrameEvents> ev) { p->on_frame(std::move(ev)); });
  return std::unique_ptr<Server>(new Server(std::move(impl)));
}

std::uint16_t Server::port() const { return impl_->port_; }
std::uint16_t Server::http_port() const { return impl_->http_ ? impl_->http_->port() : 0; }

int Server::run() {
  if (impl_->stopping_) return 0;
  impl_->begin();
  impl_->serve();
  return 0;
}

void Server::start() {
  if (impl_->io_thread_.joinable() || impl_->stopping_) return;
  impl_->begin();
  impl_->io_thread_ = std::jthread([this] { impl_->serve(); });
}

void Server::stop() {
  if (!impl_) return;
  const bool first = !impl_->stopping_.exchange(true);
  if (first) asio::post(impl_->io_, [p = impl_.get()] { p->shutdown(); });
  if (impl_->io_thread_.joinable() && impl_->io_thread_.get_id() != std::this_thread::get_id()) impl_->io_thread_.join();
}

ServerStats Server::stats() const {
  ServerStats s;
  s.frames = impl_->service_->frames_processed();
  s.clients = impl_->clients_.load();
  s.connections = impl_->connections_.load();
  s.refused = impl_->refused_.load();
  s.disconnected_slow = impl_->slow_.load();
  s.objects_failed = impl_->service_->objects_failed();
  s.faults = impl_->service_->faults() + impl_->net_faults_.load() + impl_->observer_faults_.load();
  s.tracking_alive = impl_->service_->healthy();
  s.peak_write_lines = impl_->peak_lines_.load();
  s.peak_write_bytes = impl_->peak_bytes_.load();
  s.paused = impl_->service_->paused();
  s.end_of_input = impl_->service_->end_of_input();
  return s;
}

std::vector<Clock::time_point> Server::frame_release_times() const {
  std::scoped_lock lock(impl_->release_mutex_);
  return impl_->released_;
}

}  // namespace v4r::server
