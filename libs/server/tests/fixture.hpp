// v4r - robust model-based object tracking. MIT licence.
#pragma once

// Test helpers: a rendered ship sequence (made once per test process), an in-process server on
// an ephemeral loopback port, and protocol clients.

#include <array>
#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <asio.hpp>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include "v4r/geometry/look_at.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/protocol/protocol.hpp"
#include "v4r/server/client.hpp"
#include "v4r/server/server.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::server::test {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

/// \brief A rendered sequence of the ship mockup with its ground truth.
struct Sequence {
  fs::path dir;
  std::string frames;  ///< folder of PNGs
  geometry::PinholeCamera camera;
  std::vector<geometry::SE3> truth;  ///< T_cam_obj per frame
  std::string cao;                   ///< the model text
  int count = 0;
};

inline constexpr int kFrames = 30;

/// The ship sequence, rendered once per process into a temporary folder (removed at exit).
inline const Sequence& ship_sequence() {
  static const Sequence seq = [] {
    Sequence s;
    s.dir = fs::temp_directory_path() / ("v4r_server_test_" + std::to_string(::getpid()));
    s.camera = synth::default_camera();
    s.cao = synth::ship_mockup_cao();
    synth::TrajectorySpec spec;
    spec.frames = kFrames;
    spec.T0 = geometry::look_at(0.6, -0.6, 0.75);
    s.truth = synth::make_trajectory(spec);
    synth::RenderOptions ro;
    ro.seed = 7;
    auto r = synth::write_sequence(s.dir.string(), s.cao, s.camera, s.truth, ro);
    if (!r) throw std::runtime_error(r.error().to_string());
    s.frames = (s.dir / "frames").string();
    s.count = kFrames;
    static struct Cleanup {
      fs::path dir;
      ~Cleanup() {
        std::error_code ec;
        fs::remove_all(dir, ec);
      }
    } cleanup{s.dir};
    return s;
  }();
  return seq;
}

/// Options of a test server: paused, ephemeral loopback port, no signal handling.
inline ServerOptions test_options(const Sequence& s, double fps = 30.0) {
  ServerOptions o;
  o.camera = s.camera;
  o.input = s.frames;
  o.fps = fps;
  o.port = 0;
  o.paused = true;
  o.handle_signals = false;
  return o;
}

inline std::unique_ptr<Server> start_server(ServerOptions o) {
  auto s = Server::create(std::move(o));
  if (!s) {
    ADD_FAILURE() << s.error().to_string();
    return nullptr;
  }
  (*s)->start();
  return std::move(*s);
}

inline Client connect(const Server& srv) {
  auto c = Client::connect("127.0.0.1", srv.port());
  if (!c) {
    ADD_FAILURE() << c.error().to_string();
    return Client();
  }
  return std::move(*c);
}

/// Sends a command and returns its reply line ("" after an error, which is reported).
inline std::string ask(Client& c, const std::string& line) {
  auto r = c.request(line);
  if (!r) {
    ADD_FAILURE() << line << ": " << r.error().to_string();
    return {};
  }
  return *r;
}

inline bool is_ok(const std::string& reply) { return reply.starts_with("OK "); }

inline std::string fmt_cmd(const protocol::Command& c) { return protocol::format(c); }

/// SetPose command for T_cam_obj.
inline std::string set_pose(const std::string& object, const geometry::SE3& T) {
  const Eigen::Vector3d t = T.translation(), r = T.rvec();
  return fmt_cmd(protocol::SetPose{object, {t.x(), t.y(), t.z()}, {r.x(), r.y(), r.z()}});
}

/// Gives `object` the model text with AddModel bytes=N (after AddObject).
inline void add_model_inline(Client& c, const std::string& object, const std::string& cao) {
  EXPECT_TRUE(is_ok(ask(c, "AddObject name=" + object)));
  auto r = c.request_with_payload(fmt_cmd(protocol::AddModelInline{object, protocol::ModelFormat::kCao, cao.size()}), cao);
  ASSERT_TRUE(r) << r.error().to_string();
  EXPECT_TRUE(is_ok(*r)) << *r;
}

/// Poses received by one client: object -> frame -> event.
using PoseLog = std::map<std::string, std::map<std::uint64_t, protocol::ObjectPoseEvent>>;

/// Reads events until `done(log)` or the deadline; returns false on timeout or a closed connection.
inline bool collect(Client& c, PoseLog& log, const std::function<bool(const PoseLog&)>& done,
                    std::chrono::milliseconds timeout,
                    std::function<void(const protocol::ObjectPoseEvent&)> on_pose = nullptr,
                    std::map<std::uint64_t, protocol::SystemStatusEvent>* status = nullptr) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done(log)) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    auto l = c.next_event(left);
    if (!l) return false;
    auto ev = protocol::parse_object_pose(*l);
    if (const auto* p = std::get_if<protocol::ObjectPoseEvent>(&ev)) {
      if (on_pose) on_pose(*p);
      log[p->object][p->frame] = *p;
    } else if (status) {
      auto st = protocol::parse_system_status(*l);
      if (const auto* e = std::get_if<protocol::SystemStatusEvent>(&st)) (*status)[e->frame] = *e;
    }
  }
  return true;
}

/// True when `object` has a pose for every frame 0..frames-1.
inline bool has_all(const PoseLog& log, const std::string& object, int frames) {
  auto it = log.find(object);
  if (it == log.end()) return false;
  for (int f = 0; f < frames; ++f)
    if (!it->second.count(static_cast<std::uint64_t>(f))) return false;
  return true;
}

/// GET over HTTP/1.0; returns the head and as much of the body as `max_bytes`.
inline std::string http_get(std::uint16_t port, const std::string& path, std::size_t max_bytes = 1 << 20) {
  asio::io_context io;
  asio::ip::tcp::socket s(io);
  s.connect({asio::ip::make_address("127.0.0.1"), port});
  const timeval tv{2, 0};  // a stream never ends: give up reading after 2 s of silence
  ::setsockopt(s.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  asio::write(s, asio::buffer("GET " + path + " HTTP/1.0\r\nHost: x\r\n\r\n"));
  std::string out;
  std::array<char, 8192> buf;
  // Plain recv(): Asio's blocking read would wait on past the SO_RCVTIMEO timeout.
  while (out.size() < max_bytes) {
    const ssize_t n = ::recv(s.native_handle(), buf.data(), buf.size(), 0);
    if (n <= 0) break;
    out.append(buf.data(), static_cast<std::size_t>(n));
  }
  return out;
}

inline geometry::SE3 to_se3(const protocol::ObjectPoseEvent& e) {
  return geometry::SE3(Eigen::Quaterniond(e.q[0], e.q[1], e.q[2], e.q[3]), Eigen::Vector3d(e.t[0], e.t[1], e.t[2]));
}

}  // namespace v4r::server::test
