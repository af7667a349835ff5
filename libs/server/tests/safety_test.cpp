// v4r - robust model-based object tracking. MIT licence.
// `v4r serve` is safe to expose to clients (issue 13): files only inside the operator's folders,
// a fault in one object's cycle stays with that object, held poses carry a growing covariance.
#include <atomic>
#include <cstdio>
#include <fstream>

#include <fmt/format.h>
#include <sys/stat.h>

#include "fixture.hpp"
#include "v4r/pipeline/evaluation.hpp"
#include "v4r/server/path_policy.hpp"

namespace v4r::server::test {
namespace {

/// A scratch tree: data/ (a model, a symlink out, an include out, a FIFO link), outside/, logs/.
struct Tree {
  fs::path root, data, outside, logs;
  Tree() {
    root = fs::temp_directory_path() / fmt::format("v4r_safety_{}", ::getpid());
    fs::remove_all(root);
    data = root / "data";
    outside = root / "outside";
    logs = root / "logs";
    fs::create_directories(data / "sub");
    fs::create_directories(outside);
    fs::create_directories(logs);
    const std::string cao = ship_sequence().cao;
    std::ofstream(data / "ship.cao") << cao;
    std::ofstream(data / "sub" / "part.cao") << cao;
    std::ofstream(outside / "x.cao") << cao;
    fs::create_symlink(outside / "x.cao", data / "link.cao");
    fs::create_symlink(outside, data / "out_dir");
    std::ofstream(data / "include_out.cao") << "V1\nload(\"../outside/x.cao\", t=[0, 0, 0], tu=[0, 0, 0])\n0\n0\n0\n0\n";
    std::ofstream(data / "include_in.cao") << "V1\nload(\"sub/part.cao\", t=[0, 0, 0], tu=[0, 0, 0])\n0\n0\n0\n0\n";
    // A FIFO outside: a server that opened it would block on it and never answer.
    ::mkfifo((outside / "fifo.cao").c_str(), 0600);
    fs::create_symlink(outside / "fifo.cao", data / "fifo.cao");
    fs::create_symlink(outside / "z.csv", logs / "evil.csv");
  }
  ~Tree() {
    std::error_code ec;
    fs::remove_all(root, ec);
  }
};

bool refused(const std::string& reply, const std::string& cmd) {
  return reply.starts_with("ERR " + cmd + " code=forbidden ");
}

TEST(PathPolicy, ResolvesInsideTheFoldersOnly) {
  Tree t;
  auto p = PathPolicy::create({t.data.string()}, "--data-dir");
  ASSERT_TRUE(p) << p.error().to_string();
  EXPECT_TRUE(p->resolve_read("ship.cao"));
  EXPECT_TRUE(p->resolve_read((t.data / "sub" / ".." / "ship.cao").string()));
  EXPECT_EQ(p->resolve_read("/etc/passwd").error().field, "forbidden");
  EXPECT_EQ(p->resolve_read("../outside/x.cao").error().field, "forbidden");
  EXPECT_EQ(p->resolve_read("link.cao").error().field, "forbidden");
  EXPECT_EQ(p->resolve_read("out_dir/x.cao").error().field, "forbidden");
  EXPECT_EQ(p->resolve_read("missing.cao").error().field, "io_error");
  EXPECT_EQ(p->resolve_read("sub").error().field, "io_error");  // a folder is not a model
  // A sibling folder whose name starts like the data folder is outside.
  fs::create_directories(t.root / "data2");
  std::ofstream(t.root / "data2" / "y.cao") << "V1\n";
  EXPECT_EQ(p->resolve_read((t.root / "data2" / "y.cao").string()).error().field, "forbidden");
  auto logs = PathPolicy::create({t.logs.string()}, "--log-dir");
  ASSERT_TRUE(logs);
  EXPECT_EQ(*logs->resolve_write("a.csv"), t.logs / "a.csv");
  EXPECT_EQ(logs->resolve_write("evil.csv").error().field, "forbidden");
  EXPECT_EQ(logs->resolve_write("../outside/a.csv").error().field, "forbidden");
  EXPECT_EQ(logs->resolve_write("nodir/a.csv").error().field, "io_error");
  EXPECT_EQ(logs->resolve_write("..").error().field, "forbidden");
  EXPECT_EQ(PathPolicy().resolve_write("a.csv").error().field, "forbidden");
  EXPECT_FALSE(PathPolicy::create({(t.root / "nope").string()}, "--data-dir"));
}

// Requests for files outside the operator's folders are refused with `forbidden` and touch
// nothing; inside them, models load and logs are written.
TEST(ServerSafety, FilesOnlyInsideDataDirAndLogDir) {
  Tree t;
  const Sequence& seq = ship_sequence();
  ServerOptions o = test_options(seq, 0.0);
  o.data_dirs = {t.data.string()};
  o.log_dir = t.logs.string();
  auto srv = start_server(o);
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  ASSERT_TRUE(is_ok(ask(c, "AddObject name=a")));
  EXPECT_TRUE(refused(ask(c, "AddModel object=a path=/etc/passwd format=cao"), "AddModel"));
  EXPECT_TRUE(refused(ask(c, "AddModel object=a path=../outside/x.cao"), "AddModel"));
  EXPECT_TRUE(refused(ask(c, "AddModel object=a path=" + (t.outside / "x.cao").string()), "AddModel"));
  EXPECT_TRUE(refused(ask(c, "AddModel object=a path=link.cao"), "AddModel"));
  EXPECT_TRUE(refused(ask(c, "AddModel object=a path=out_dir/x.cao"), "AddModel"));
  // The FIFO behind the link is never opened: the reply comes (a read would block forever).
  EXPECT_TRUE(refused(ask(c, "AddModel object=a path=fifo.cao"), "AddModel"));
  // Includes are bounded too, in files and in inline models.
  EXPECT_TRUE(refused(ask(c, "AddModel object=a path=include_out.cao"), "AddModel"));
  const std::string inline_out = "V1\nload(\"/etc/passwd\", t=[0, 0, 0], tu=[0, 0, 0])\n0\n0\n0\n0\n";
  auto r = c.request_with_payload(fmt::format("AddModel object=a format=cao bytes={}", inline_out.size()), inline_out);
  ASSERT_TRUE(r);
  EXPECT_TRUE(refused(*r, "AddModel")) << *r;
  EXPECT_TRUE(ask(c, "AddModel object=a path=missing.cao").starts_with("ERR AddModel code=io_error")) << "inside: told";
  // Inside: loads (relative to the first data folder, absolute, and through an include).
  EXPECT_TRUE(ask(c, "AddModel object=a path=ship.cao").starts_with("OK AddModel object=a junctions="));
  EXPECT_TRUE(is_ok(ask(c, "AddModel object=a path=" + (t.data / "sub" / "part.cao").string())));
  EXPECT_TRUE(is_ok(ask(c, "AddModel object=a path=include_in.cao")));

  // Logs: only inside --log-dir, never through a symlink; nothing is created when refused.
  const bool tmp_x_existed = fs::exists("/tmp/x.csv");
  EXPECT_TRUE(refused(ask(c, "Log on file=/tmp/x.csv"), "Log"));
  EXPECT_EQ(fs::exists("/tmp/x.csv"), tmp_x_existed);
  EXPECT_TRUE(refused(ask(c, "Log on file=" + (t.outside / "y.csv").string()), "Log"));
  EXPECT_TRUE(refused(ask(c, "Log on file=../outside/y.csv"), "Log"));
  EXPECT_TRUE(refused(ask(c, "Log on file=evil.csv"), "Log"));
  EXPECT_FALSE(fs::exists(t.outside / "y.csv"));
  EXPECT_FALSE(fs::exists(t.outside / "z.csv"));
  EXPECT_EQ(ask(c, "Log on file=cycles.csv"), "OK Log on file=cycles.csv");
  EXPECT_TRUE(is_ok(ask(c, set_pose("a", seq.truth[0]))));
  EXPECT_TRUE(is_ok(ask(c, "Start")));
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (!srv->stats().end_of_input && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(ask(c, "Log off"), "OK Log off");
  std::ifstream in(t.logs / "cycles.csv");
  std::string header;
  std::getline(in, header);
  EXPECT_TRUE(header.starts_with("frame,stamp_s,cycle_ms")) << header;
  // Written again (an earlier cycle log may be overwritten): it starts afresh.
  EXPECT_TRUE(is_ok(ask(c, "Log on file=cycles.csv")));
  EXPECT_EQ(ask(c, "Log off"), "OK Log off");
  std::ifstream again(t.logs / "cycles.csv");
  std::getline(again, header);
  EXPECT_TRUE(header.starts_with("frame,stamp_s,cycle_ms")) << header;
  EXPECT_FALSE(std::getline(again, header)) << "no rows while paused at the end";
  EXPECT_EQ(srv->stats().faults, 0u);
}

TEST(ServerSafety, LogFileIsRefusedWithoutLogDir) {
  Tree t;
  ServerOptions o = test_options(ship_sequence());
  o.data_dirs = {t.data.string()};
  auto srv = start_server(o);
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  EXPECT_TRUE(refused(ask(c, "Log on file=cycles.csv"), "Log"));
  EXPECT_TRUE(refused(ask(c, "Log on file=" + (t.logs / "cycles.csv").string()), "Log"));
  EXPECT_FALSE(fs::exists(t.logs / "cycles.csv"));
  EXPECT_EQ(ask(c, "Ping"), "OK Ping");
}

// An object whose cycle throws reports `failed` (ObjectPose and SystemStatus); another object on
// the same server keeps every frame, tracked as before.
TEST(ServerSafety, AnObjectWhoseCycleThrowsFailsAloneTheOthersKeepEveryFrame) {
  const Sequence& seq = ship_sequence();
  ServerOptions o = test_options(seq, 0.0);
  std::atomic<int> bad_cycles{0};
  constexpr int kFaultAt = 5;  // the bad object's 6th cycle throws
  o.object_hook = [&](const std::string& object) {
    if (object == "bad" && bad_cycles++ == kFaultAt) throw std::runtime_error("injected fault");
  };
  auto srv = start_server(o);
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  add_model_inline(c, "ship", seq.cao);
  add_model_inline(c, "bad", seq.cao);
  EXPECT_TRUE(is_ok(ask(c, set_pose("ship", seq.truth[0]))));
  EXPECT_TRUE(is_ok(ask(c, set_pose("bad", seq.truth[0]))));
  EXPECT_TRUE(is_ok(ask(c, "Subscribe what=ObjectPose")));
  EXPECT_TRUE(is_ok(ask(c, "Subscribe what=SystemStatus")));
  EXPECT_TRUE(is_ok(ask(c, "Start")));
  PoseLog log;
  std::map<std::uint64_t, protocol::SystemStatusEvent> status;
  EXPECT_TRUE(collect(
      c, log,
      [&](const PoseLog& l) {
        return has_all(l, "ship", seq.count) && has_all(l, "bad", seq.count) && status.count(seq.count - 1);
      },
      30s, nullptr, &status));
  for (int f = 0; f < seq.count; ++f) {
    const auto& ship = log["ship"][static_cast<std::uint64_t>(f)];
    EXPECT_EQ(ship.status, protocol::TrackStatus::kTracking) << "frame " << f;
    const auto& bad = log["bad"][static_cast<std::uint64_t>(f)];
    EXPECT_EQ(bad.status == protocol::TrackStatus::kFailed, f >= kFaultAt) << "frame " << f;
  }
  EXPECT_LT(pipeline::evaluate([&] {
              std::vector<geometry::SE3> est;
              for (const auto& [f, e] : log.at("ship")) est.push_back(to_se3(e));
              return est;
            }(),
                               seq.truth)
                .mean_translation_m,
            2e-3);
  ASSERT_TRUE(status.count(seq.count - 1));
  EXPECT_EQ(status.at(kFaultAt - 1).failed, 0u);
  EXPECT_EQ(status.at(seq.count - 1).failed, 1u);
  EXPECT_EQ(srv->stats().objects_failed, 1);
  EXPECT_TRUE(srv->stats().tracking_alive);
  EXPECT_EQ(bad_cycles.load(), kFaultAt + 1) << "a failed object is not run again";
  EXPECT_EQ(ask(c, "Ping"), "OK Ping");
  // SetPose starts it again.
  EXPECT_TRUE(is_ok(ask(c, set_pose("bad", seq.truth[0]))));
  EXPECT_EQ(srv->stats().objects_failed, 0);
}

// A lost object is published with the filter's prediction covariance, growing frame by frame,
// not with the covariance of its last good frame.
TEST(ServerSafety, LostObjectCarriesAGrowingPredictionCovariance) {
  const Sequence& seq = ship_sequence();
  ServerOptions o = test_options(seq, 0.0);
  // Without the search: once the ghost's templates are built (on their own thread, after a
  // number of frames that depends on the machine) it would be searched for, without a pose.
  o.search.enabled = false;
  auto srv = start_server(o);
  ASSERT_TRUE(srv);
  Client c = connect(*srv);
  add_model_inline(c, "ship", seq.cao);
  add_model_inline(c, "ghost", seq.cao);
  EXPECT_TRUE(is_ok(ask(c, set_pose("ship", seq.truth[0]))));
  // Far outside the field of view: nothing of it can be measured, it is lost from frame 0 on.
  EXPECT_TRUE(is_ok(ask(c, "SetPose object=ghost t=3,0,1 r=0,0,0")));
  EXPECT_TRUE(is_ok(ask(c, "Subscribe what=ObjectPose")));
  EXPECT_TRUE(is_ok(ask(c, "Start")));
  PoseLog log;
  EXPECT_TRUE(collect(
      c, log, [&](const PoseLog& l) { return has_all(l, "ship", seq.count) && has_all(l, "ghost", seq.count); }, 30s));
  double prev_t = 0.0, prev_r = 0.0;
  for (int f = 0; f < seq.count; ++f) {
    const auto& g = log["ghost"][static_cast<std::uint64_t>(f)];
    ASSERT_EQ(g.status, protocol::TrackStatus::kLost) << "frame " << f;
    const double var_t = g.cov[0] + g.cov[7] + g.cov[14], var_r = g.cov[21] + g.cov[28] + g.cov[35];
    if (f > 0) {
      EXPECT_GT(var_t, prev_t) << "frame " << f;
      EXPECT_GT(var_r, prev_r) << "frame " << f;
    }
    prev_t = var_t;
    prev_r = var_r;
  }
  // After a second lost, the position is uncertain by centimetres, not by a tracked pose's 0.1 mm.
  const auto& ship = log["ship"][static_cast<std::uint64_t>(seq.count - 1)];
  EXPECT_EQ(ship.status, protocol::TrackStatus::kTracking);
  EXPECT_GT(prev_t, 100.0 * (ship.cov[0] + ship.cov[7] + ship.cov[14]));
  EXPECT_GT(std::sqrt(prev_t), 0.01);
}

}  // namespace
}  // namespace v4r::server::test
