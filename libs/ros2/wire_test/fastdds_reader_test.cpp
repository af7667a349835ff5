// v4r - robust model-based object tracking. MIT licence.
//
// ROS 2 on the wire, checked by the other DDS vendor. This process is built on eProsima Fast DDS
// with the message types written by hand here from ROS 2's .msg definitions
// (third_party/ros2_interfaces); `v4r serve --ros2` speaks Cyclone DDS.
//  1. serve tracks a rendered sequence and publishes; Fast DDS reads rt/v4r/box/pose,
//     rt/v4r/box/status and rt/tf: every pose with the frame's stamp (frame / fps), the frame id,
//     and exactly the pose and covariance the TCP protocol reports for the same frame.
//  2. Fast DDS publishes the sequence as Image (mono8) + CameraInfo; serve (`--input ros2:/camera`,
//     calibration from camera_info) tracks every image, stamped with the image's header; the
//     image-written-to-pose-read time is printed (p50 / p99).
// Both vendors are held to loopback: Cyclone through CYCLONEDDS_URI, Fast DDS through a UDPv4
// transport on 127.0.0.1 with 127.0.0.1 as its only initial peer.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
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
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

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

/// sensor_msgs/msg/Image (written here, read by v4r).
struct ImageMsg {
  Header header;
  std::uint32_t height = 0, width = 0;
  std::string encoding;
  std::uint8_t is_bigendian = 0;
  std::uint32_t step = 0;
  std::vector<std::uint8_t> data;
  void write(Cdr& c) const {
    c << header.sec << header.nanosec << header.frame_id << height << width << encoding << is_bigendian << step;
    c << data;
  }
};

/// sensor_msgs/msg/CameraInfo (with its RegionOfInterest).
struct CameraInfoMsg {
  Header header;
  std::uint32_t height = 0, width = 0;
  std::string distortion_model = "plumb_bob";
  std::vector<double> d;
  std::array<double, 9> k{}, r{};
  std::array<double, 12> p{};
  std::uint32_t binning_x = 0, binning_y = 0;
  std::uint32_t roi_x = 0, roi_y = 0, roi_h = 0, roi_w = 0;
  bool roi_rectify = false;
  void write(Cdr& c) const {
    c << header.sec << header.nanosec << header.frame_id << height << width << distortion_model << d;
    c.serializeArray(k.data(), k.size());
    c.serializeArray(r.data(), r.size());
    c.serializeArray(p.data(), p.size());
    c << binning_x << binning_y << roi_x << roi_y << roi_h << roi_w << roi_rectify;
  }
};

/// A write-only TopicDataType for one of the messages above.
template <class Msg>
class WriteType : public fdds::TopicDataType {
 public:
  WriteType(const char* name, std::uint32_t max_size) {
    this->setName(name);
    this->m_typeSize = max_size;
    this->m_isGetKeyDefined = false;
  }
  bool serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) override {
    FastBuffer fb(reinterpret_cast<char*>(payload->data), payload->max_size);
    Cdr c(fb, Cdr::DEFAULT_ENDIAN, Cdr::DDS_CDR);
    payload->encapsulation = c.endianness() == Cdr::BIG_ENDIANNESS ? CDR_BE : CDR_LE;
    try {
      c.serialize_encapsulation();
      static_cast<const Msg*>(data)->write(c);
    } catch (...) {
      return false;
    }
    payload->length = static_cast<std::uint32_t>(c.getSerializedDataLength());
    return true;
  }
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t*, void*) override { return false; }
  std::function<std::uint32_t()> getSerializedSizeProvider(void*) override {
    return [n = this->m_typeSize] { return n; };
  }
  void* createData() override { return new Msg(); }
  void deleteData(void* data) override { delete static_cast<Msg*>(data); }
  bool getKey(void*, eprosima::fastrtps::rtps::InstanceHandle_t*, bool) override { return false; }
};

/// Cyclone's configuration for serve: loopback only, unicast discovery.
void write_cyclone_config(const fs::path& file) {
  std::ofstream x(file);
  x << "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface address=\"127.0.0.1\"/>"
       "</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto"
       "</ParticipantIndex><MaxAutoParticipantIndex>20</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/>"
       "</Peers></Discovery></Domain></CycloneDDS>\n";
}

/// A Fast DDS participant on 127.0.0.1 only (UDPv4), with 127.0.0.1 as its only initial peer.
fdds::DomainParticipant* loopback_participant(int domain) {
  fdds::DomainParticipantQos pqos;
  pqos.transport().use_builtin_transports = false;
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  udp->interfaceWhiteList.emplace_back("127.0.0.1");
  pqos.transport().user_transports.push_back(udp);
  eprosima::fastrtps::rtps::Locator_t peer;
  eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
  pqos.wire_protocol().builtin.initialPeersList.push_back(peer);
  pqos.wire_protocol().builtin.metatrafficMulticastLocatorList.clear();
  return fdds::DomainParticipantFactory::get_instance()->create_participant(static_cast<fdds::DomainId_t>(domain),
                                                                            pqos);
}

/// Starts `v4r serve ARGS` in `dir` with Cyclone held to loopback; output to `out`.
pid_t start_serve(const fs::path& dir, const std::string& args, const fs::path& out) {
  write_cyclone_config(dir / "cyclone.xml");
  const std::string cmd = "cd " + dir.string() + " && CYCLONEDDS_URI=file://" + (dir / "cyclone.xml").string() +
                          " exec " + std::string(V4R_CLI) + " serve " + args + " >" + out.string() + " 2>&1";
  const pid_t child = fork();
  if (child == 0) {
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  return child;
}

/// The protocol port serve printed, or 0 after `tries` x 50 ms (while `poll` runs between tries).
int wait_port(const fs::path& out, int tries, const std::function<void()>& poll = {}) {
  for (int i = 0; i < tries; ++i) {
    if (poll) poll();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const std::string s = slurp(out);
    const auto at = s.find("protocol on 127.0.0.1:");
    if (at != std::string::npos) return std::atoi(s.c_str() + at + 22);
  }
  return 0;
}

/// "SetPose object=box t=... r=..." from a rendered sequence's init_pose.txt.
std::string set_pose_line(const fs::path& init_pose) {
  std::string pose_line;
  std::ifstream f(init_pose);
  for (std::string l; std::getline(f, l);)
    if (!l.empty() && l[0] != '#') pose_line = l;
  std::stringstream ps(pose_line);
  double v[6];
  for (double& x : v) ps >> x;
  std::ostringstream setpose;
  setpose.precision(17);
  setpose << "SetPose object=box t=" << v[0] << "," << v[1] << "," << v[2] << " r=" << v[3] << "," << v[4] << ","
          << v[5];
  return setpose.str();
}

}  // namespace

TEST(Ros2Wire, FastDdsReaderGetsEveryPoseOfCycloneWriter) {
  const fs::path dir = fs::temp_directory_path() / ("v4r_ros2_wire_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_EQ(std::system((std::string(V4R_CLI) + " render --model box --frames " + std::to_string(kFrames) + " --out " +
                         (dir / "seq").string() + " >/dev/null")
                            .c_str()),
            0);
  const int domain = 1 + static_cast<int>(::getpid() % 200);

  // Fast DDS (the reader, here) and Cyclone (the writer, in v4r serve) on loopback only.
  fdds::DomainParticipant* participant = loopback_participant(domain);
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
  const pid_t child = start_serve(dir, "--camera seq/camera.yaml --input seq/frames --fps " +
                                           std::to_string(static_cast<int>(kFps)) + " --paused --port 0 --ros2 " +
                                           "--ros2-domain " + std::to_string(domain), out);
  ASSERT_GT(child, 0);
  const int port = wait_port(out, 200);
  ASSERT_GT(port, 0) << slurp(out);
  Client c;
  ASSERT_TRUE(c.connect_to(port));
  EXPECT_EQ(c.line(std::chrono::seconds(5)).rfind("Hello", 0), 0u);
  for (const std::string& l :
       {std::string("AddObject name=box"), std::string("AddModel object=box path=seq/model.cao"),
        set_pose_line(dir / "seq" / "init_pose.txt"), std::string("Subscribe what=ObjectPose")}) {
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

// The other direction: this process publishes the rendered sequence as ROS 2 Image (mono8) and
// CameraInfo messages (Fast DDS), `v4r serve --input ros2:/camera --ros2` takes its calibration
// from camera_info (no --camera) and tracks the images; every frame's ObjectPose carries the
// image's stamp and is within 5 cm / 5 degrees of the truth. The time from writing an image here
// to reading its pose back here over DDS (two DDS hops plus the vision cycle) is printed as p50 /
// p99: an upper bound of v4r's image-received-to-pose-published latency.
TEST(Ros2Wire, CycloneReaderTracksImagesAndCameraInfoFromFastDds) {
  const fs::path dir = fs::temp_directory_path() / ("v4r_ros2_images_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_EQ(std::system((std::string(V4R_CLI) + " render --model box --frames " + std::to_string(kFrames) +
                         " --out " + (dir / "seq").string() + " >/dev/null")
                            .c_str()),
            0);
  const int domain = 1 + static_cast<int>((::getpid() + 100) % 200);
  fdds::DomainParticipant* participant = loopback_participant(domain);
  ASSERT_NE(participant, nullptr);
  fdds::TypeSupport image_type(new WriteType<ImageMsg>("sensor_msgs::msg::dds_::Image_", 4u << 20));
  fdds::TypeSupport info_type(new WriteType<CameraInfoMsg>("sensor_msgs::msg::dds_::CameraInfo_", 4096));
  fdds::TypeSupport pose_type(new ReadType<PoseMsg>("geometry_msgs::msg::dds_::PoseWithCovarianceStamped_", 4096));
  ASSERT_EQ(image_type.register_type(participant), ReturnCode_t::RETCODE_OK);
  ASSERT_EQ(info_type.register_type(participant), ReturnCode_t::RETCODE_OK);
  ASSERT_EQ(pose_type.register_type(participant), ReturnCode_t::RETCODE_OK);
  fdds::Publisher* pub = participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  fdds::Subscriber* sub = participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  auto* image_topic = participant->create_topic("rt/camera/image_raw", image_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  auto* info_topic = participant->create_topic("rt/camera/camera_info", info_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  auto* pose_topic = participant->create_topic("rt/v4r/box/pose", pose_type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
  fdds::DataWriterQos wqos = fdds::DATAWRITER_QOS_DEFAULT;
  wqos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  wqos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  wqos.history().depth = 1;
  wqos.publish_mode().kind = fdds::ASYNCHRONOUS_PUBLISH_MODE;  // images are fragmented
  fdds::DataWriter* image_writer = pub->create_datawriter(image_topic, wqos);
  fdds::DataWriter* info_writer = pub->create_datawriter(info_topic, wqos);
  ASSERT_TRUE(image_writer && info_writer);
  fdds::DataReaderQos rqos = fdds::DATAREADER_QOS_DEFAULT;
  rqos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
  rqos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  rqos.history().depth = 10;
  Collector<PoseMsg> poses;
  ASSERT_NE(sub->create_datareader(pose_topic, rqos, &poses), nullptr);

  // The sequence as ROS 2 messages.
  cv::FileStorage fsr((dir / "seq" / "camera.yaml").string(), cv::FileStorage::READ);
  cv::Mat K, D;
  fsr["camera_matrix"] >> K;
  fsr["distortion_coefficients"] >> D;
  CameraInfoMsg info;
  info.header.frame_id = "test_camera_optical";
  info.width = static_cast<std::uint32_t>(static_cast<int>(fsr["image_width"]));
  info.height = static_cast<std::uint32_t>(static_cast<int>(fsr["image_height"]));
  for (int i = 0; i < 9; ++i) info.k[static_cast<std::size_t>(i)] = K.at<double>(i / 3, i % 3);
  for (int i = 0; i < 5; ++i) info.d.push_back(D.at<double>(i));
  info.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::vector<ImageMsg> images(kFrames);
  for (int i = 0; i < kFrames; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", i);
    const cv::Mat img = cv::imread((dir / "seq" / "frames" / name).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(img.empty());
    ImageMsg& m = images[static_cast<std::size_t>(i)];
    m.header.sec = 1000;
    m.header.nanosec = static_cast<std::uint32_t>(std::lround(i / kFps * 1e9));
    m.header.frame_id = "test_camera_optical";
    m.height = static_cast<std::uint32_t>(img.rows);
    m.width = static_cast<std::uint32_t>(img.cols);
    m.encoding = "mono8";
    m.step = static_cast<std::uint32_t>(img.cols);
    m.data.assign(img.data, img.data + img.total());
  }
  const auto truth = [&] {
    std::vector<std::vector<double>> rows;
    std::ifstream in(dir / "seq" / "gt.csv");
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) rows.push_back(numbers(line));
    return rows;
  }();

  // serve waits for camera_info, then for its first image: both are offered until it listens.
  const fs::path out = dir / "serve.out";
  const pid_t child = start_serve(dir, "--input ros2:/camera --paused --port 0 --ros2 --ros2-domain " +
                                           std::to_string(domain), out);
  ASSERT_GT(child, 0);
  const int port = wait_port(out, 600, [&] {
    info.header = images[0].header;
    info_writer->write(&info);
    image_writer->write(&images[0]);
  });
  ASSERT_GT(port, 0) << slurp(out);
  EXPECT_NE(slurp(out).find("waiting for camera_info"), std::string::npos);
  Client c;
  ASSERT_TRUE(c.connect_to(port));
  EXPECT_EQ(c.line(std::chrono::seconds(5)).rfind("Hello", 0), 0u);
  for (const std::string& l : {std::string("AddObject name=box"), std::string("AddModel object=box path=seq/model.cao"),
                               set_pose_line(dir / "seq" / "init_pose.txt"), std::string("Subscribe what=ObjectPose")}) {
    c.send(l);
    const std::string reply = c.line(std::chrono::seconds(10));
    EXPECT_EQ(reply.rfind("OK", 0), 0u) << l << " -> " << reply;
  }
  c.send("Start");
  std::map<int, ProtocolPose> got;
  std::vector<double> latency_ms;
  const auto wait_frame = [&](int i) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (std::chrono::steady_clock::now() < end) {
      const std::string l = c.line(std::chrono::seconds(1));
      if (l.rfind("ObjectPose", 0) != 0) continue;
      const ProtocolPose p = parse_pose_line(l);
      const int frame = static_cast<int>(std::lround((p.stamp - 1000.0) * kFps));
      got[frame] = p;
      if (frame == i) return true;
    }
    return false;
  };
  EXPECT_TRUE(wait_frame(0)) << slurp(out);
  std::size_t seen = poses.samples().size();
  for (int i = 1; i < kFrames; ++i) {
    const auto sent = std::chrono::steady_clock::now();
    ASSERT_TRUE(image_writer->write(&images[static_cast<std::size_t>(i)])) << "frame " << i;
    EXPECT_TRUE(wait_frame(i)) << "no ObjectPose for frame " << i;
    // The same pose over DDS: image written here -> pose read here.
    if (poses.wait_samples(seen + 1, std::chrono::seconds(2))) {
      latency_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - sent).count());
      seen = poses.samples().size();
    }
  }
  kill(child, SIGINT);
  int status = 0;
  waitpid(child, &status, 0);

  int accurate = 0;
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_TRUE(got.count(i)) << "frame " << i;
    const ProtocolPose& p = got[i];
    EXPECT_NEAR(p.stamp, 1000.0 + i / kFps, 1e-6);
    const std::vector<double>& g = truth[static_cast<std::size_t>(i)];  // frame, t, q (w x y z)
    const double dt = std::sqrt(std::pow(p.t[0] - g[1], 2) + std::pow(p.t[1] - g[2], 2) + std::pow(p.t[2] - g[3], 2));
    const double dot = std::abs(p.q[0] * g[4] + p.q[1] * g[5] + p.q[2] * g[6] + p.q[3] * g[7]);
    const double deg = 2.0 * std::acos(std::min(1.0, dot)) * 180.0 / M_PI;
    if (dt < 0.05 && deg < 5.0) ++accurate;
  }
  EXPECT_GE(accurate, static_cast<int>(std::ceil(0.95 * kFrames)));
  const std::vector<PoseMsg> dds_poses = poses.samples();
  ASSERT_FALSE(dds_poses.empty());
  for (const PoseMsg& m : dds_poses) {
    EXPECT_EQ(m.header.sec, 1000);
    EXPECT_EQ(m.header.frame_id, "camera_optical_frame");
  }
  ASSERT_GE(latency_ms.size(), static_cast<std::size_t>(kFrames / 2));
  std::sort(latency_ms.begin(), latency_ms.end());
  const auto at = [&](double q) {
    return latency_ms[std::min(latency_ms.size() - 1, static_cast<std::size_t>(q * (latency_ms.size() - 1) + 0.5))];
  };
  std::printf("DDS image written -> pose read (Fast DDS -> v4r serve (Cyclone) -> Fast DDS, %zu frames): "
              "p50 %.3f ms, p99 %.3f ms, max %.3f ms\n",
              latency_ms.size(), at(0.5), at(0.99), latency_ms.back());
  RecordProperty("latency_p50_ms", std::to_string(at(0.5)));
  RecordProperty("latency_p99_ms", std::to_string(at(0.99)));
  participant->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant);
  fs::remove_all(dir);
}
