// v4r - robust model-based object tracking. MIT licence.
// Loopback tests of `v4r serve`: objects built over the protocol track a rendered sequence as
// accurately as `v4r track`; abuse, overload and authentication leave well-behaved clients alone.
#include <atomic>
#include <fstream>
#include <future>
#include <thread>

#include <asio.hpp>
#include <sys/socket.h>
#include <sys/time.h>
#include <fmt/format.h>

#include "fixture.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/pipeline/evaluation.hpp"

namespace v4r::server::test {
namespace {

/// A raw connection with a tiny receive buffer, for clients that never read.
struct RawClient {
  asio::io_context io;
  asio::ip::tcp::socket socket{io};
  explicit RawClient(std::uint16_t port) {
    socket.open(asio::ip::tcp::v4());
    socket.set_option(asio::socket_base::receive_buffer_size(4096));
    socket.connect({asio::ip::make_address("127.0.0.1"), port});
  }
  void send(const std::string& s) { asio::write(socket, asio::buffer(s)); }
  /// Closes with a reset (SO_LINGER 0), as a killed process with unread data would.
  void kill() {
    asio::error_code ec;
    socket.set_option(asio::socket_base::linger(true, 0), ec);
    socket.close(ec);
  }
};

void build_from_features(Client& c, const std::string& object, const model::Model& m) {
  ASSERT_TRUE(is_ok(ask(c, "AddObject name=" + object)));
  for (std::size_t i = 0; i < m.junctions().size(); ++i) {
    const Eigen::Vector3d& p = m.junctions()[i].p;
    const std::string r = ask(c, fmt_cmd(protocol::AddJunction{object, fmt::format("j{}", i), {p.x(), p.y(), p.z()}}));
    ASSERT_TRUE(is_ok(r)) << r;
  }
  for (std::size_t i = 0; i < m.lines().size(); ++i) {
    const model::LineEdge& l = m.lines()[i];
    const std::string r =
        ask(c, fmt_cmd(protocol::AddLine{object, fmt::format("l{}", i), fmt::format("j{}", l.a), fmt::format("j{}", l.b)}));
    ASSERT_TRUE(is_ok(r)) << r;
  }
}

pipeline::AccuracyStats accuracy(const PoseLog& log, const std::string& object, const Sequence& seq) {
  std::vector<geometry::SE3> est;
  for (const auto& [f, e] : log.at(object)) est.push_back(to_se3(e));
  return pipeline::evaluate(est, seq.truth);
}

// (1) One client builds an object with AddModel bytes=N, another one with AddFeature only; both
// set the initial pose and subscribe; after Start both receive an ObjectPose per frame per object.
TEST(Server, ObjectsFromAddModelAndFromAddFeatureTrackEveryFrameAccurately) {
  const Sequence& seq = ship_sequence();
  auto srv = start_server(test_options(seq));
  ASSERT_TRUE(srv);
  Client a = connect(*srv), b = connect(*srv);
  EXPECT_EQ(a.greeting(), "Hello version=1");

  add_model_inline(a, "ship_cao", seq.cao);
  auto ship = model::parse_cao(seq.cao, "ship");
  ASSERT_TRUE(ship);
  build_from_features(b, "ship_feat", *ship);
  EXPECT_TRUE(is_ok(ask(a, set_pose("ship_cao", seq.truth[0]))));
  EXPECT_TRUE(is_ok(ask(b, set_pose("ship_feat", seq.truth[0]))));
  EXPECT_TRUE(is_ok(ask(a, "Subscribe what=ObjectPose")));
  EXPECT_TRUE(is_ok(ask(b, "Subscribe what=ObjectPose")));
  EXPECT_TRUE(is_ok(ask(b, "Subscribe what=SystemStatus")));
  const std::string start = ask(a, "Start");
  EXPECT_EQ(start, "OK Start frame=0");

  auto all = [&](const PoseLog& l) { return has_all(l, "ship_cao", seq.count) && has_all(l, "ship_feat", seq.count); };
  PoseLog log_a, log_b;
  std::map<std::uint64_t, protocol::SystemStatusEvent> status;
  auto fut = std::async(std::launch::async, [&] { return collect(b, log_b, all, 10s, nullptr, &status); });
  EXPECT_TRUE(collect(a, log_a, all, 10s));
  EXPECT_TRUE(fut.get());
  ASSERT_TRUE(has_all(log_a, "ship_cao", seq.count));
  ASSERT_TRUE(has_all(log_a, "ship_feat", seq.count));
  ASSERT_TRUE(has_all(log_b, "ship_cao", seq.count));
  ASSERT_TRUE(has_all(log_b, "ship_feat", seq.count));
  // Both clients see the same poses, with their covariance and stamps.
  for (const std::string obj : {"ship_cao", "ship_feat"})
    for (const auto& [f, e] : log_a.at(obj)) {
      EXPECT_EQ(e, log_b.at(obj).at(f));
      EXPECT_NEAR(e.stamp, f / 30.0, 1e-9);
      EXPECT_GT(e.cov[0], 0.0);
    }

  // A SystemStatus per frame (the last one may still be on its way), counting features of both objects.
  collect(b, log_b, [&](const PoseLog&) { return status.size() >= static_cast<std::size_t>(seq.count); }, 2s, nullptr,
          &status);
  ASSERT_EQ(status.size(), static_cast<std::size_t>(seq.count));
  for (const auto& [f, st] : status) {
    EXPECT_EQ(st.features_found, st.features_used + st.outliers) << f;
    EXPECT_GE(st.features_used, 16u) << f;  // 12 to 15 tracked edges per object
    EXPECT_GT(st.cycle_ms, 0.0);
  }

  const auto acc_cao = accuracy(log_a, "ship_cao", seq), acc_feat = accuracy(log_a, "ship_feat", seq);
  std::printf("[ server ] ship via AddModel:   mean %.3f mm (max %.3f), %.3f deg; %d/%d successes\n",
              acc_cao.mean_translation_m * 1e3, acc_cao.max_translation_m * 1e3, acc_cao.mean_rotation_deg,
              acc_cao.successes, acc_cao.frames);
  std::printf("[ server ] ship via AddFeature: mean %.3f mm (max %.3f), %.3f deg; %d/%d successes\n",
              acc_feat.mean_translation_m * 1e3, acc_feat.max_translation_m * 1e3, acc_feat.mean_rotation_deg,
              acc_feat.successes, acc_feat.frames);
  EXPECT_LT(acc_cao.mean_translation_m, 2e-3);
  EXPECT_LT(acc_cao.mean_rotation_deg, 0.5);
  EXPECT_EQ(acc_cao.successes, seq.count);
  EXPECT_LT(acc_feat.mean_translation_m, 5e-3);
  EXPECT_EQ(acc_feat.successes, seq.count);
  for (const auto& [f, e] : log_a.at("ship_cao")) EXPECT_EQ(e.status, protocol::TrackStatus::kTracking) << f;

  // At the end of the input the server keeps serving.
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (!srv->stats().end_of_input && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(10ms);
  EXPECT_TRUE(srv->stats().end_of_input);
  EXPECT_EQ(srv->stats().frames, seq.count);
  EXPECT_EQ(ask(a, "Ping"), "OK Ping");
  EXPECT_EQ(ask(b, "Start"), fmt::format("OK Start frame={} end=1", seq.count));
}

// (2) Garbage, over-long lines, oversized and cut-off payloads, NaN, unknown commands: one ERR
// each, and the server, the tracking and the other clients carry on.
TEST(Server, AbuseGetsOneErrEachAndLeavesOtherClientsStreaming) {
  const Sequence& seq = ship_sequence();
  auto srv = start_server(test_options(seq, 15.0));
  ASSERT_TRUE(srv);
  Client w = connect(*srv);
  add_model_inline(w, "ship", seq.cao);
  EXPECT_TRUE(is_ok(ask(w, set_pose("ship", seq.truth[0]))));
  EXPECT_TRUE(is_ok(ask(w, "Subscribe what=ObjectPose")));
  // A client that starts an AddModel payload and vanishes halfway: nothing is applied.
  {
    Client cut = connect(*srv);
    EXPECT_TRUE(is_ok(ask(cut, "AddObject name=cut")));
    EXPECT_TRUE(is_ok(ask(cut, set_pose("cut", seq.truth[0]))));
    ASSERT_TRUE(cut.send_raw(fmt_cmd(protocol::AddModelInline{"cut", protocol::ModelFormat::kCao, seq.cao.size()}) +
                             "\n" + seq.cao.substr(0, seq.cao.size() / 2)));
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_TRUE(is_ok(ask(w, "Start")));

  PoseLog log;
  auto fut = std::async(std::launch::async, [&] {
    return collect(w, log, [&](const PoseLog& l) { return has_all(l, "ship", seq.count); }, 15s);
  });

  Client g = connect(*srv);
  auto expect_err = [&](const std::string& bytes, const std::string& prefix) {
    ASSERT_TRUE(g.send_raw(bytes));
    auto r = g.read_line();
    ASSERT_TRUE(r) << r.error().to_string();
    EXPECT_TRUE(r->starts_with(prefix)) << "sent " << bytes.substr(0, 60) << " got " << *r;
  };
  expect_err(std::string("\x01\x02\x03 garbage \xff\n"), "ERR ");
  expect_err("hello world\n", "ERR ");
  expect_err("Frobnicate x=1\n", "ERR Frobnicate code=unknown_command");
  expect_err(std::string(10000, 'A') + "\n", "ERR ");
  expect_err("Ping\n", "OK Ping");  // the rest of the long line was dropped: no second ERR
  expect_err("SetPose object=" + std::string(5000, 'x') + " t=0,0,1 r=0,0,0\n", "ERR SetPose code=too_long");
  expect_err("SetPose object=ship t=nan,0,0.5 r=0,0,0\n", "ERR SetPose code=not_finite");
  expect_err("SetPose object=ship t=1e999,0,0.5 r=0,0,0\n", "ERR SetPose code=not_finite");
  expect_err("SetPose object=ship t=0,0,0.5\n", "ERR SetPose code=missing_argument");
  expect_err("SetPose object=nobody t=0,0,0.5 r=0,0,0\n", "ERR SetPose code=unknown_object");
  expect_err("SetParam name=track.rows value=nan\n", "ERR SetParam");
  expect_err("AddFeature object=ship type=junction id=j0 p=0,0,inf\n", "ERR AddFeature code=not_finite");
  // A model that does not parse, then an oversized announcement whose bytes are skipped.
  expect_err("AddModel object=ship format=cao bytes=12\nnot a model\n", "ERR AddModel code=bad_model");
  expect_err("AddModel object=ship format=dxf bytes=15\nPing\nPing\nPing\n", "ERR AddModel code=bad_argument");
  expect_err("Ping\r\n", "OK Ping");  // the 15 bytes of the refused AddModel were skipped
  // An oversized announcement: the stream cannot be followed any more, the server hangs up.
  expect_err(fmt::format("AddModel object=ship format=cao bytes={}\n", protocol::kMaxPayloadBytes + 1), "ERR AddModel code=too_large");
  EXPECT_FALSE(g.read_line(2s));
  g = connect(*srv);
  // Clients vanishing without a word, some with unread events.
  for (int i = 0; i < 5; ++i) {
    RawClient r(srv->port());
    r.send("Subscribe what=ObjectPose\nSubscribe what=SystemStatus\n");
    std::this_thread::sleep_for(30ms);
    r.kill();
  }
  EXPECT_TRUE(fut.get()) << "the well-behaved client missed frames";
  EXPECT_TRUE(has_all(log, "ship", seq.count));
  EXPECT_EQ(log.count("cut"), 0u) << "a cut-off payload was applied";
  EXPECT_LT(accuracy(log, "ship", seq).mean_translation_m, 2e-3);
  EXPECT_EQ(ask(g, "Ping"), "OK Ping");
  EXPECT_EQ(ask(w, "RemoveObject name=cut"), "OK RemoveObject name=cut");
}

// (3) 100 subscribed clients, one that never reads, one that floods commands without reading,
// and clients killed mid-stream: every well-behaved client receives every frame's pose.
TEST(Server, HundredClientsAndBadOnesEveryWellBehavedClientGetsEveryFrame) {
  const Sequence& seq = ship_sequence();
  ServerOptions o = test_options(seq);
  o.max_replies = 32;
  o.close_grace = 300ms;
  auto srv = start_server(o);
  ASSERT_TRUE(srv);
  Client setup = connect(*srv);
  add_model_inline(setup, "ship", seq.cao);
  EXPECT_TRUE(is_ok(ask(setup, set_pose("ship", seq.truth[0]))));

  constexpr int kClients = 100, kKilled = 10;
  std::vector<Client> clients;
  for (int i = 0; i < kClients + kKilled; ++i) {
    clients.push_back(connect(*srv));
    ASSERT_TRUE(is_ok(ask(clients.back(), "Subscribe what=ObjectPose")));
  }
  RawClient never_reads(srv->port());
  never_reads.send("Subscribe what=ObjectPose\nSubscribe what=SystemStatus\n");
  RawClient flooder(srv->port());
  std::string flood;
  for (int i = 0; i < 4000; ++i) flood += "ListParams\n";

  EXPECT_TRUE(is_ok(ask(setup, "Start")));
  std::vector<PoseLog> logs(kClients + kKilled);
  std::vector<std::future<bool>> futs;
  for (int i = 0; i < kClients + kKilled; ++i) {
    futs.push_back(std::async(std::launch::async, [&, i] {
      if (i >= kClients) {  // read a few frames, then die
        collect(clients[i], logs[i], [&](const PoseLog& l) { return l.count("ship") && l.at("ship").size() >= 5; }, 10s);
        clients[i].close();
        return true;
      }
      return collect(clients[i], logs[i], [&](const PoseLog& l) { return has_all(l, "ship", seq.count); }, 20s);
    }));
  }
  // Processes killed mid-stream with unread events: their connections end with a reset.
  std::vector<std::unique_ptr<RawClient>> doomed;
  for (int i = 0; i < 5; ++i) {
    doomed.push_back(std::make_unique<RawClient>(srv->port()));
    doomed.back()->send("Subscribe what=ObjectPose\nSubscribe what=SystemStatus\n");
  }
  std::thread killer([&] {
    std::this_thread::sleep_for(300ms);  // about frame 9
    for (auto& d : doomed) d->kill();
  });
  std::thread flood_thread([&] {
    asio::error_code ec;
    asio::write(flooder.socket, asio::buffer(flood), ec);  // fails once the server hangs up: fine
  });
  int complete = 0;
  for (auto& f : futs) complete += f.get() ? 1 : 0;
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (srv->stats().disconnected_slow == 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(10ms);
  flooder.kill();
  flood_thread.join();
  killer.join();
  EXPECT_EQ(complete, kClients + kKilled);
  for (int i = 0; i < kClients; ++i) EXPECT_TRUE(has_all(logs[i], "ship", seq.count)) << "client " << i;
  const ServerStats st = srv->stats();
  std::printf("[ server ] %llu connections, %zu clients now, %llu dropped for not reading\n",
              static_cast<unsigned long long>(st.connections), st.clients,
              static_cast<unsigned long long>(st.disconnected_slow));
  EXPECT_GE(st.disconnected_slow, 1u) << "the flooding client was not dropped";
  EXPECT_EQ(ask(setup, "Ping"), "OK Ping");
  never_reads.kill();
}

// (4) With a token (required on any non-loopback address; here on loopback), every command before
// `Auth` gets ERR code=unauthorized, payloads of refused commands are skipped.
TEST(Server, TokenRequiresAuthBeforeAnyCommand) {
  const Sequence& seq = ship_sequence();
  {
    ServerOptions o = test_options(seq);
    o.bind = "0.0.0.0";
    auto s = Server::create(o);
    ASSERT_FALSE(s);
    EXPECT_NE(s.error().message.find("--token"), std::string::npos) << s.error().message;
    o.bind = "not-an-address";
    EXPECT_FALSE(Server::create(o));
  }
  ServerOptions o = test_options(seq);
  o.token = "s3cret";
  o.http_port = 0;
  auto srv = start_server(o);
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  EXPECT_EQ(c.greeting(), "Hello version=1 auth=required");
  // The monitoring page wants the token too.
  EXPECT_TRUE(http_get(srv->http_port(), "/status.json").starts_with("HTTP/1.0 401"));
  EXPECT_TRUE(http_get(srv->http_port(), "/status.json?token=guess").starts_with("HTTP/1.0 401"));
  EXPECT_TRUE(http_get(srv->http_port(), "/status.json?x=1&token=s3cret").starts_with("HTTP/1.0 200"));
  EXPECT_TRUE(ask(c, "Ping").starts_with("ERR Ping code=unauthorized")) << "Ping before Auth";
  EXPECT_TRUE(ask(c, "AddObject name=x").starts_with("ERR AddObject code=unauthorized"));
  EXPECT_TRUE(ask(c, "Subscribe what=ObjectPose").starts_with("ERR Subscribe code=unauthorized"));
  auto r = c.request_with_payload("AddModel object=x format=cao bytes=11", "Ping\nPing\nP");
  ASSERT_TRUE(r);
  EXPECT_TRUE(r->starts_with("ERR AddModel code=unauthorized")) << *r;
  EXPECT_TRUE(ask(c, "Auth token=wrong").starts_with("ERR Auth code=unauthorized"));
  EXPECT_EQ(ask(c, "Auth token=s3cret"), "OK Auth");
  EXPECT_EQ(ask(c, "Ping"), "OK Ping");  // the payload's "Ping" lines were not run
  EXPECT_EQ(ask(c, "AddObject name=x"), "OK AddObject name=x");
  // Three wrong tokens close the connection.
  Client d = connect(*srv);
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(ask(d, "Auth token=guess").starts_with("ERR Auth"));
  EXPECT_FALSE(d.read_line(2s));
}

TEST(Server, PauseHoldsTheInputAndStartResumesWithTheNextFrame) {
  const Sequence& seq = ship_sequence();
  auto srv = start_server(test_options(seq, 30.0));
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  add_model_inline(c, "ship", seq.cao);
  EXPECT_TRUE(is_ok(ask(c, set_pose("ship", seq.truth[0]))));
  EXPECT_TRUE(is_ok(ask(c, "Subscribe what=ObjectPose")));
  // Paused at frame 0: nothing is processed.
  std::this_thread::sleep_for(150ms);
  EXPECT_EQ(srv->stats().frames, 0);
  EXPECT_FALSE(c.next_event(100ms));
  EXPECT_TRUE(is_ok(ask(c, "Start")));
  PoseLog log;
  EXPECT_TRUE(collect(c, log, [](const PoseLog& l) { return l.count("ship") && l.at("ship").size() >= 5; }, 5s));
  const std::string pause = ask(c, "Pause");
  ASSERT_TRUE(pause.starts_with("OK Pause frame=")) << pause;
  const int held = std::stoi(pause.substr(std::string("OK Pause frame=").size()));
  // Events of frames processed before the Pause may still arrive; then nothing.
  collect(c, log, [](const PoseLog&) { return false; }, 200ms);
  const std::int64_t frames = srv->stats().frames;
  EXPECT_EQ(frames, held);
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(srv->stats().frames, frames);
  EXPECT_FALSE(c.next_event(50ms));
  EXPECT_EQ(ask(c, "Start"), fmt::format("OK Start frame={}", held));
  EXPECT_TRUE(collect(c, log, [&](const PoseLog& l) { return has_all(l, "ship", seq.count); }, 5s));
  EXPECT_EQ(log.at("ship").size(), static_cast<std::size_t>(seq.count));  // no frame twice, none skipped
}

TEST(Server, ParametersListGetSetThroughTheRegistry) {
  const Sequence& seq = ship_sequence();
  auto srv = start_server(test_options(seq));
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  const std::string list = ask(c, "ListParams");
  ASSERT_TRUE(list.starts_with("OK ListParams count=")) << list;
  EXPECT_NE(list.find(" track.rows="), std::string::npos);
  const std::string get = ask(c, "GetParam name=search.half_width");
  EXPECT_TRUE(get.starts_with("OK GetParam name=search.half_width value=16")) << get;
  EXPECT_EQ(ask(c, "SetParam name=search.half_width value=20"), "OK SetParam name=search.half_width value=20");
  EXPECT_TRUE(ask(c, "GetParam name=search.half_width").starts_with("OK GetParam name=search.half_width value=20"));
  EXPECT_TRUE(ask(c, "SetParam name=search.half_width value=-3").starts_with("ERR SetParam code=bad_value"));
  EXPECT_TRUE(ask(c, "SetParam name=search_half_widht value=3").starts_with("ERR SetParam code=unknown_param"));
  EXPECT_TRUE(ask(c, "GetParam name=nope").starts_with("ERR GetParam code=unknown_param"));
}

TEST(Server, FeatureErrorsAndRemovalWhileTracking) {
  const Sequence& seq = ship_sequence();
  auto srv = start_server(test_options(seq));
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  auto ship = model::parse_cao(seq.cao, "ship");
  ASSERT_TRUE(ship);
  EXPECT_TRUE(ask(c, "AddFeature object=ship type=junction id=a p=0,0,0").starts_with("ERR AddFeature code=unknown_object"));
  build_from_features(c, "ship", *ship);
  EXPECT_TRUE(ask(c, "AddObject name=ship").starts_with("ERR AddObject code=exists"));
  EXPECT_TRUE(ask(c, "AddFeature object=ship type=junction id=j0 p=0,0,0").starts_with("ERR AddFeature code=exists"));
  EXPECT_TRUE(ask(c, "AddFeature object=ship type=line id=lx from=j0 to=zz").starts_with("ERR AddFeature code=unknown_feature"));
  EXPECT_TRUE(ask(c, "RemoveFeature object=ship id=j0").starts_with("ERR RemoveFeature"));  // used by lines
  EXPECT_TRUE(ask(c, "RemoveFeature object=ship id=nope").starts_with("ERR RemoveFeature code=unknown_feature"));
  EXPECT_TRUE(is_ok(ask(c, set_pose("ship", seq.truth[0]))));
  EXPECT_TRUE(is_ok(ask(c, "Subscribe what=ObjectPose")));
  EXPECT_TRUE(is_ok(ask(c, "Start")));
  PoseLog log;
  EXPECT_TRUE(collect(c, log, [](const PoseLog& l) { return l.count("ship") && l.at("ship").size() >= 8; }, 5s));
  // Removing and re-adding a line while tracking keeps the object tracked.
  EXPECT_EQ(ask(c, "RemoveFeature object=ship id=l0"),
            fmt::format("OK RemoveFeature object=ship id=l0 junctions={} lines={} circles=0", ship->junctions().size(),
                        ship->lines().size() - 1));
  const auto& l0 = ship->lines()[0];
  EXPECT_TRUE(is_ok(ask(c, fmt::format("AddFeature object=ship type=line id=l0 from=j{} to=j{}", l0.a, l0.b))));
  EXPECT_TRUE(is_ok(ask(c, "AddFeature object=ship type=circle id=c0 center=0,0,0.5 normal=0,0,1 radius=0.01")));
  EXPECT_TRUE(collect(c, log, [&](const PoseLog& l) { return has_all(l, "ship", seq.count); }, 5s));
  std::vector<geometry::SE3> est;
  for (const auto& [f, e] : log.at("ship")) est.push_back(to_se3(e));
  const auto acc = pipeline::evaluate(est, seq.truth);
  EXPECT_EQ(acc.successes, seq.count);
  EXPECT_TRUE(is_ok(ask(c, "RemoveObject name=ship")));
  EXPECT_TRUE(ask(c, "RemoveObject name=ship").starts_with("ERR RemoveObject code=unknown_object"));
}

TEST(Server, QuitClosesOnlyThatClientAndMaxClientsRefusesMore) {
  const Sequence& seq = ship_sequence();
  ServerOptions o = test_options(seq);
  o.max_clients = 2;
  auto srv = start_server(o);
  ASSERT_TRUE(srv);
  Client a = connect(*srv), b = connect(*srv);
  auto third = Client::connect("127.0.0.1", srv->port());
  ASSERT_TRUE(third) << third.error().to_string();
  EXPECT_TRUE(third->greeting().starts_with("ERR ? code=busy")) << third->greeting();
  EXPECT_FALSE(third->read_line(2s));  // and closed
  EXPECT_EQ(ask(a, "Quit"), "OK Quit");
  EXPECT_FALSE(a.read_line(2s));  // closed
  EXPECT_EQ(ask(b, "Ping"), "OK Ping");
  // The slot is free again (the server drops the session asynchronously).
  std::this_thread::sleep_for(100ms);
  Client c = connect(*srv);
  EXPECT_EQ(ask(c, "Ping"), "OK Ping");
}

TEST(Server, LogWritesOneCsvRowPerCycle) {
  const Sequence& seq = ship_sequence();
  ServerOptions o = test_options(seq, 0.0);  // as fast as it goes
  o.log_dir = seq.dir.string();             // `Log on file=` writes only there
  auto srv = start_server(o);
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  add_model_inline(c, "ship", seq.cao);
  EXPECT_TRUE(is_ok(ask(c, set_pose("ship", seq.truth[0]))));
  const fs::path csv = seq.dir / "cycles.csv";
  EXPECT_EQ(ask(c, "Log on file=" + csv.string()), "OK Log on file=" + csv.string());
  EXPECT_TRUE(ask(c, "Log on file=nodir/x.csv").starts_with("ERR Log code=io_error"));
  EXPECT_TRUE(ask(c, "Log on file=/nonexistent/dir/x.csv").starts_with("ERR Log code=forbidden"));
  // Existing files other than cycle logs are not overwritten.
  EXPECT_TRUE(ask(c, "Log on file=" + (seq.dir / "gt.csv").string()).starts_with("ERR Log code=io_error"));
  EXPECT_GT(fs::file_size(seq.dir / "gt.csv"), 100u);
  EXPECT_TRUE(is_ok(ask(c, "Log on file=" + csv.string())));
  EXPECT_TRUE(is_ok(ask(c, "Start")));
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (!srv->stats().end_of_input && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(ask(c, "Log off"), "OK Log off");
  std::ifstream in(csv);
  std::string header, row;
  std::getline(in, header);
  EXPECT_TRUE(header.starts_with("frame,stamp_s,cycle_ms,visibility_ms,track_ms,solve_ms")) << header;
  int rows = 0;
  while (std::getline(in, row)) {
    EXPECT_TRUE(row.starts_with(std::to_string(rows) + ",")) << row;
    ++rows;
  }
  EXPECT_EQ(rows, seq.count);
}

TEST(Server, HttpMonitorServesPageStatusAndMjpegStream) {
  const Sequence& seq = ship_sequence();
  ServerOptions o = test_options(seq, 30.0);
  o.http_port = 0;
  auto srv = start_server(o);
  ASSERT_TRUE(srv);
  ASSERT_GT(srv->http_port(), 0);
  Client c = connect(*srv);
  add_model_inline(c, "ship", seq.cao);
  EXPECT_TRUE(is_ok(ask(c, set_pose("ship", seq.truth[0]))));
  EXPECT_EQ(ask(c, "Display on"), "OK Display on");
  EXPECT_TRUE(is_ok(ask(c, "Start")));
  const std::string page = http_get(srv->http_port(), "/");
  EXPECT_TRUE(page.starts_with("HTTP/1.0 200 OK")) << page.substr(0, 100);
  EXPECT_NE(page.find("/stream.mjpg"), std::string::npos);
  EXPECT_TRUE(http_get(srv->http_port(), "/nope").starts_with("HTTP/1.0 404"));
  // Two JPEG parts of the stream.
  const std::string stream = http_get(srv->http_port(), "/stream.mjpg", 80000);
  EXPECT_NE(stream.find("multipart/x-mixed-replace; boundary=v4rframe"), std::string::npos);
  const auto p1 = stream.find("--v4rframe\r\nContent-Type: image/jpeg");
  ASSERT_NE(p1, std::string::npos);
  const auto body = stream.find("\r\n\r\n", p1) + 4;
  ASSERT_LT(body + 2, stream.size());
  EXPECT_EQ(static_cast<unsigned char>(stream[body]), 0xFF);  // JPEG SOI
  EXPECT_EQ(static_cast<unsigned char>(stream[body + 1]), 0xD8);
  const std::string status = http_get(srv->http_port(), "/status.json");
  EXPECT_NE(status.find("application/json"), std::string::npos);
  EXPECT_NE(status.find("\"objects\":[{\"object\":\"ship\",\"status\":\"tracking\""), std::string::npos) << status;
}

// The Python example client (standard library only) against the server.
TEST(Server, PythonExampleClientTracksTheSequence) {
  if (std::system("python3 -c 'import socket' > /dev/null 2>&1") != 0) GTEST_SKIP() << "no python3";
  const Sequence& seq = ship_sequence();
  auto srv = start_server(test_options(seq));
  ASSERT_TRUE(srv);
  const Eigen::Vector3d t = seq.truth[0].translation(), r = seq.truth[0].rvec();
  const fs::path out = seq.dir / "python_client.txt";
  const std::string cmd =
      fmt::format("python3 {}/examples/python/v4r_client.py --port {} --object ship --model {} "
                  "--pose \"{:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\" --start --frames {} > {} 2>&1",
                  V4R_SOURCE_DIR, srv->port(), (seq.dir / "model.cao").string(), t.x(), t.y(), t.z(), r.x(), r.y(),
                  r.z(), seq.count, out.string());
  EXPECT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream in(out);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("OK AddModel object=ship junctions=24 lines=35 circles=0"), std::string::npos) << text;
  EXPECT_NE(text.find(fmt::format("frame {} ", seq.count - 1)), std::string::npos) << text;
  EXPECT_EQ(text.find("lost"), std::string::npos) << text;
}

}  // namespace
}  // namespace v4r::server::test
