// v4r - robust model-based object tracking. MIT licence.
//
// ROS 2 on the wire, checked by the other DDS vendor: `v4r serve --ros2` (Cyclone DDS) tracks a
// rendered sequence while this process, built on eProsima Fast DDS with the message types written
// by hand here from ROS 2's .msg definitions (third_party/ros2_interfaces), reads
// rt/v4r/box/pose, rt/v4r/box/status and rt/tf. Every pose must arrive with the frame's stamp
// (frame / fps), the frame id, and exactly the pose and covariance the TCP protocol reports for
// the same frame. Both vendors are held to loopback (Cyclone through CYCLONEDDS_URI, Fast DDS
// through a UDPv4 transport on 127.0.0.1 and 127.0.0.1 as the only initial peer).
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <gtest/gtest.h>

namespace fs = std::filesystem;
namespace fdds = eprosima::fastdds::dds;
using eprosima::fastcdr::Cdr;
using eprosima::fastcdr::FastBuffer;

namespace {

constexpr int kFrames = 30;
constexpr double kFps = 30.0;

// ---- Message types written by hand from ROS 2's .msg files (plain CDR, fields in order). ----

struct Header {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
  std::string frame_id;
  void read(Cdr& d) { d >> sec >> nanosec >> frame_id; }
};

/// geometry_msgs/msg/PoseWithCovarianceStamped
struct PoseMsg {
  Header header;
  std::array<double, 3> position{};
  std::array<double, 4> orientation{};  ///< x y z w
  std::array<double, 36> covariance{};
  void read(Cdr& d) {
    header.read(d);
    for (double& v : position) d >> v;
    for (double& v : orientation) d >> v;
    d.deserializeArray(covariance.data(), covariance.size());
  }
};

/// tf2_msgs/msg/TFMessage (of geometry_msgs/msg/TransformStamped)
struct TfMsg {
  struct Transform {
    Header header;
    std::string child_frame_id;
    std::array<double, 3> translation{};
    std::array<double, 4> rotation{};
  };
  std::vector<Transform> transforms;
  void read(Cdr& d) {
    std::uint32_t n = 0;
    d >> n;
    transforms.resize(n);
    for (Transform& t : transforms) {
      t.header.read(d);
      d >> t.child_frame_id;
      for (double& v : t.translation) d >> v;
      for (double& v : t.rotation) d >> v;
    }
  }
};

/// std_msgs/msg/String
struct StringMsg {
  std::string data;
  void read(Cdr& d) { d >> data; }
};

/// A read-only TopicDataType for one of the messages above.
template <class Msg>
class ReadType : public fdds::TopicDataType {
 public:
  ReadType(const char* name, std::uint32_t max_size) {
    this->setName(name);
    this->m_typeSize = max_size;
    this->m_isGetKeyDefined = false;
  }
  bool serialize(void*, eprosima::fastrtps::rtps::SerializedPayload_t*) override { return false; }
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override {
    FastBuffer fb(reinterpret_cast<char*>(payload->data), payload->length);
    Cdr d(fb, Cdr::DEFAULT_ENDIAN, Cdr::DDS_CDR);
    try {
      d.read_encapsulation();
      static_cast<Msg*>(data)->read(d);
    } catch (...) {
      return false;
    }
    return true;
  }
  std::function<std::uint32_t()> getSerializedSizeProvider(void*) override {
    return [n = this->m_typeSize] { return n; };
  }
  void* createData() override { return new Msg(); }
  void deleteData(void* data) override { delete static_cast<Msg*>(data); }
  bool getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) override { return false; }
};

/// Collects every sample of one topic.
template <class Msg>
class Collector : public fdds::DataReaderListener {
 public:
  void on_data_available(fdds::DataReader* reader) override {
    Msg m;
    fdds::SampleInfo info;
    while (reader->take_next_sample(&m, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      std::scoped_lock lock(mutex_);
      samples_.push_back(m);
    }
    cv_.notify_all();
  }
  void on_subscription_matched(fdds::DataReader*, const fdds::SubscriptionMatchedStatus& s) override {
    std::scoped_lock lock(mutex_);
    matched_ = s.current_count;
    cv_.notify_all();
  }
  bool wait_samples(std::size_t n, std::chrono::seconds timeout) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] { return samples_.size() >= n; });
  }
  bool wait_matched(std::chrono::seconds timeout) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] { return matched_ > 0; });
  }
  std::vector<Msg> samples() {
    std::scoped_lock lock(mutex_);
    return samples_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Msg> samples_;
  int matched_ = 0;
};

/// A ObjectPose line of the TCP protocol: frame, stamp, t, q (w x y z), cov.
struct ProtocolPose {
  int frame = -1;
  double stamp = 0;
  std::vector<double> t, q, cov;
  std::string status;
};

std::vector<double> numbers(const std::string& csv) {
  std::vector<double> v;
  std::stringstream ss(csv);
  for (std::string x; std::getline(ss, x, ',');) v.push_back(std::stod(x));
  return v;
}

ProtocolPose parse_pose_line(const std::string& line) {
  ProtocolPose p;
  std::stringstream ss(line);
  for (std::string kv; ss >> kv;) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos) continue;
    const std::string k = kv.substr(0, eq), v = kv.substr(eq + 1);
    if (k == "frame") p.frame = std::stoi(v);
    if (k == "stamp") p.stamp = std::stod(v);
    if (k == "t") p.t = numbers(v);
    if (k == "q") p.q = numbers(v);
    if (k == "cov") p.cov = numbers(v);
    if (k == "status") p.status = v;
  }
  return p;
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// A line-based TCP client of the protocol.
class Client {
 public:
  bool connect_to(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    return ::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  }
  ~Client() {
    if (fd_ >= 0) ::close(fd_);
  }
  void send(const std::string& line) {
    const std::string l = line + "\n";
    ASSERT_EQ(::write(fd_, l.data(), l.size()), static_cast<ssize_t>(l.size()));
  }
  /// The next line (without LF), or "" after `timeout` or at EOF.
  std::string line(std::chrono::seconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      const auto nl = buf_.find('\n');
      if (nl != std::string::npos) {
        std::string l = buf_.substr(0, nl);
        buf_.erase(0, nl + 1);
        return l;
      }
      if (std::chrono::steady_clock::now() > end) return {};
      timeval tv{0, 100000};
      setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
      char b[4096];
      const ssize_t n = ::read(fd_, b, sizeof b);
      if (n == 0) return {};
      if (n > 0) buf_.append(b, static_cast<std::size_t>(n));
    }
  }

 private:
  int fd_ = -1;
  std::string buf_;
};

}  // namespace

TEST(Ros2Wire, FastDdsReaderGetsEveryPoseOfCycloneWriter) {
  const fs::path dir = fs::temp_directory_path() / ("v4r_ros2_wire_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string cli = V4R_CLI;
  ASSERT_EQ(std::system((cli + " render --model box --frames " + std::to_string(kFrames) + " --out " +
                         (dir / "seq").string() + " >/dev/null")
                            .c_str()),
            0);
  const int domain = 1 + static_cast<int>(::getpid() % 200);

  // Cyclone (the writer, in v4r serve): loopback only, unicast discovery.
  {
    std::ofstream x(dir / "cyclone.xml");
    x << "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface address=\"127.0.0.1\"/>"
         "</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto"
         "</ParticipantIndex><MaxAutoParticipantIndex>20</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/>"
         "</Peers></Discovery></Domain></CycloneDDS>\n";
  }

  // Fast DDS (the reader, here): UDPv4 on 127.0.0.1 only, 127.0.0.1 as initial peer.
  fdds::DomainParticipantQos pqos;
  pqos.transport().use_builtin_transports = false;
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  udp->interfaceWhiteList.emplace_back("127.0.0.1");
  pqos.transport().user_transports.push_back(udp);
  eprosima::fastrtps::rtps::Locator_t peer;
  eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
  pqos.wire_protocol().builtin.initialPeersList.push_back(peer);
  pqos.wire_protocol().builtin.metatrafficMulticastLocatorList.clear();
  fdds::DomainParticipant* participant =
      fdds::DomainParticipantFactory::get_instance()->create_participant(static_cast<fdds::DomainId_t>(domain), pqos);
  ASSERT_NE(participant, nullptr);
  fdds::TypeSupport pose_type(new ReadType<PoseMsg>("geometry_msgs::msg::dds_::PoseWithCovarianceStamped_", 4096));
  fdds::TypeSupport tf_type(new ReadType<TfMsg>("tf2_msgs::msg::dds_::TFMessage_", 65536));
  fdds::TypeSupport string_type(new ReadType<StringMsg>("std_msgs::msg::dds_::String_", 1024));
  ASSERT_EQ(pose_type.register_type(participant), ReturnCode_t::RETCODE_OK);
  ASSERT_EQ(tf_type.register_type(participant), ReturnCode_t::RETCODE_OK);
  ASSERT_EQ(string_type.register_type(participant), ReturnCode_t::RETCODE_OK);
  fdds::Subscriber* sub = participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  fdds::DataReaderQos rqos = fdds::DATAREADER_QOS_DEFAULT;
  rqos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  rqos.durability().kind = fdds::VOLATILE_DURABILITY_QOS;
  rqos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  rqos.history().depth = 10;
  Collector<PoseMsg> poses;
  Collector<TfMsg> tfs;
  Collector<StringMsg> statuses;
  auto* pose_topic = participant->create_topic("rt/v4r/box/pose", pose_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  auto* tf_topic = participant->create_topic("rt/tf", tf_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  auto* status_topic = participant->create_topic("rt/v4r/box/status", string_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  ASSERT_TRUE(pose_topic && tf_topic && status_topic);
  ASSERT_NE(sub->create_datareader(pose_topic, rqos, &poses), nullptr);
  ASSERT_NE(sub->create_datareader(tf_topic, rqos, &tfs), nullptr);
  ASSERT_NE(sub->create_datareader(status_topic, rqos, &statuses), nullptr);

  // v4r serve with --ros2, paused until the readers are matched.
  const fs::path out = dir / "serve.out";
  const std::string cmd = "cd " + dir.string() + " && CYCLONEDDS_URI=file://" + (dir / "cyclone.xml").string() +
                          " exec " + cli + " serve --camera seq/camera.yaml --input seq/frames --fps " +
                          std::to_string(static_cast<int>(kFps)) + " --paused --port 0 --ros2 --ros2-domain " +
                          std::to_string(domain) + " >" + out.string() + " 2>&1";
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  int port = 0;
  for (int i = 0; i < 200 && port == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const std::string s = slurp(out);
    const auto at = s.find("protocol on 127.0.0.1:");
    if (at != std::string::npos) port = std::atoi(s.c_str() + at + 22);
  }
  ASSERT_GT(port, 0) << slurp(out);
  Client c;
  ASSERT_TRUE(c.connect_to(port));
  EXPECT_EQ(c.line(std::chrono::seconds(5)).rfind("Hello", 0), 0u);
  std::string pose_line;
  {
    std::ifstream f(dir / "seq" / "init_pose.txt");
    for (std::string l; std::getline(f, l);)
      if (!l.empty() && l[0] != '#') pose_line = l;
  }
  std::stringstream ps(pose_line);
  double v[6];
  for (double& x : v) ps >> x;
  std::ostringstream setpose;
  setpose.precision(17);
  setpose << "SetPose object=box t=" << v[0] << "," << v[1] << "," << v[2] << " r=" << v[3] << "," << v[4] << ","
          << v[5];
  for (const std::string& l :
       {std::string("AddObject name=box"), std::string("AddModel object=box path=seq/model.cao"), setpose.str(),
        std::string("Subscribe what=ObjectPose")}) {
    c.send(l);
    const std::string reply = c.line(std::chrono::seconds(10));
    EXPECT_EQ(reply.rfind("OK", 0), 0u) << l << " -> " << reply;
  }
  // The pose and status topics are created with the object's first pose; they match within
  // milliseconds once the participants know each other (through /tf, matched first).
  EXPECT_TRUE(tfs.wait_matched(std::chrono::seconds(20))) << "no Cyclone writer on rt/tf matched";
  // Discovery is two-sided: wait until Cyclone (in serve) also matched this reader, as it logs.
  bool writer_matched = false;
  for (int i = 0; i < 400 && !writer_matched; ++i) {
    writer_matched = slurp(out).find("rt/tf has 1 subscriber") != std::string::npos;
    if (!writer_matched) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_TRUE(writer_matched) << slurp(out);
  c.send("Start");
  EXPECT_EQ(c.line(std::chrono::seconds(10)).rfind("OK Start", 0), 0u);
  std::map<int, ProtocolPose> protocol;
  while (static_cast<int>(protocol.size()) < kFrames) {
    const std::string l = c.line(std::chrono::seconds(20));
    if (l.empty()) break;
    if (l.rfind("ObjectPose", 0) != 0) continue;
    const ProtocolPose p = parse_pose_line(l);
    protocol[p.frame] = p;
  }
  ASSERT_EQ(static_cast<int>(protocol.size()), kFrames) << slurp(out);
  poses.wait_samples(kFrames, std::chrono::seconds(10));
  tfs.wait_samples(kFrames, std::chrono::seconds(5));
  statuses.wait_samples(kFrames, std::chrono::seconds(5));
  kill(child, SIGINT);
  int status = 0;
  waitpid(child, &status, 0);

  const std::vector<PoseMsg> got = poses.samples();
  // The first frame's writer is created when the object first appears: its first sample may be
  // written before the reader matched (VOLATILE). Every later one must arrive.
  ASSERT_GE(static_cast<int>(got.size()), kFrames - 1) << "poses received over DDS";
  int checked = 0;
  for (const PoseMsg& m : got) {
    const double stamp = m.header.sec + m.header.nanosec * 1e-9;
    const int frame = static_cast<int>(std::lround(stamp * kFps));
    ASSERT_TRUE(protocol.count(frame)) << "stamp " << stamp;
    const ProtocolPose& p = protocol[frame];
    EXPECT_NEAR(stamp, frame / kFps, 1e-9);
    EXPECT_NEAR(stamp, p.stamp, 1e-9);
    EXPECT_EQ(m.header.frame_id, "camera_optical_frame");
    for (int i = 0; i < 3; ++i) EXPECT_EQ(m.position[static_cast<std::size_t>(i)], p.t[static_cast<std::size_t>(i)]);
    // ROS: x y z w; the protocol: w x y z.
    EXPECT_EQ(m.orientation[3], p.q[0]);
    EXPECT_EQ(m.orientation[0], p.q[1]);
    EXPECT_EQ(m.orientation[1], p.q[2]);
    EXPECT_EQ(m.orientation[2], p.q[3]);
    ASSERT_EQ(p.cov.size(), 36u);
    for (std::size_t i = 0; i < 36; ++i) EXPECT_EQ(m.covariance[i], p.cov[i]) << "frame " << frame << " cov " << i;
    EXPECT_GT(m.covariance[0], 0.0);
    EXPECT_GT(m.covariance[35], 0.0);
    ++checked;
  }
  EXPECT_GE(checked, kFrames - 1);
  const std::vector<TfMsg> tf = tfs.samples();
  EXPECT_GE(static_cast<int>(tf.size()), kFrames - 1);
  for (const TfMsg& t : tf) {
    ASSERT_EQ(t.transforms.size(), 1u);
    EXPECT_EQ(t.transforms[0].header.frame_id, "camera_optical_frame");
    EXPECT_EQ(t.transforms[0].child_frame_id, "box");
  }
  const std::vector<StringMsg> st = statuses.samples();
  EXPECT_GE(static_cast<int>(st.size()), kFrames - 1);
  for (const StringMsg& s : st) EXPECT_EQ(s.data, "tracking");
  participant->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
  fs::remove_all(dir);
}
