// v4r - robust model-based object tracking. MIT licence.
// A small client of `v4r serve` with the C++ client library (v4r::server::Client): sends a model
// and an initial pose, subscribes to the object's poses and prints them.
//
//   v4r serve --camera seq/camera.yaml --input seq/frames --paused &
//   v4r_client_example --model seq/model.cao --pose "$(tail -1 seq/init_pose.txt)" --start --frames 30
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "v4r/protocol/protocol.hpp"
#include "v4r/server/client.hpp"

namespace {

int usage() {
  std::fprintf(stderr,
               "usage: v4r_client_example --model FILE.cao --pose \"tx ty tz rx ry rz\" [--host H] [--port P]\n"
               "                          [--object NAME] [--token SECRET] [--start] [--frames N]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string host = "127.0.0.1", object = "object", model_path, pose_text, token;
  int port = 5757, frames = 0;
  bool start = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--start") start = true;
    else if (a == "--host" && has_value) host = argv[++i];
    else if (a == "--port" && has_value) port = std::stoi(argv[++i]);
    else if (a == "--object" && has_value) object = argv[++i];
    else if (a == "--model" && has_value) model_path = argv[++i];
    else if (a == "--pose" && has_value) pose_text = argv[++i];
    else if (a == "--token" && has_value) token = argv[++i];
    else if (a == "--frames" && has_value) frames = std::stoi(argv[++i]);
    else return usage();
  }
  if (model_path.empty() || pose_text.empty()) return usage();
  std::ifstream in(model_path, std::ios::binary);
  if (!in) {
    std::fprintf(stderr, "cannot read %s\n", model_path.c_str());
    return 1;
  }
  const std::string model((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  v4r::protocol::SetPose pose{object, {}, {}};
  std::istringstream ps(pose_text);
  if (!(ps >> pose.t[0] >> pose.t[1] >> pose.t[2] >> pose.r[0] >> pose.r[1] >> pose.r[2])) return usage();

  auto client = v4r::server::Client::connect(host, static_cast<std::uint16_t>(port));
  if (!client) {
    std::fprintf(stderr, "%s\n", client.error().to_string().c_str());
    return 1;
  }
  v4r::server::Client& c = *client;
  // Each command's reply: "OK ..." goes on, "ERR ..." stops.
  auto run = [&](const v4r::Expected<std::string>& reply) {
    if (!reply) {
      std::fprintf(stderr, "%s\n", reply.error().to_string().c_str());
      return false;
    }
    std::printf("%s\n", reply->c_str());
    return reply->starts_with("OK ");
  };
  namespace p = v4r::protocol;
  if (!token.empty() && !run(c.request(p::format(p::Auth{token})))) return 1;
  if (!run(c.request(p::format(p::AddObject{object})))) return 1;
  if (!run(c.request_with_payload(p::format(p::AddModelInline{object, p::ModelFormat::kCao, model.size()}), model)))
    return 1;
  if (!run(c.request(p::format(pose)))) return 1;
  if (!run(c.request(p::format(p::Subscribe{p::Topic::kObjectPose, 0.0})))) return 1;
  if (start && !run(c.request(p::format(p::Start{})))) return 1;

  for (int n = 0; frames == 0 || n < frames;) {
    auto line = c.next_event(std::chrono::seconds(10));
    if (!line) {
      std::fprintf(stderr, "%s\n", line.error().to_string().c_str());
      return 1;
    }
    auto ev = p::parse_object_pose(*line);
    const auto* e = std::get_if<p::ObjectPoseEvent>(&ev);
    if (!e || e->object != object) continue;
    std::printf("frame %llu  t = %.4f %.4f %.4f m  q = %.4f %.4f %.4f %.4f  quality %.2f  %s\n",
                static_cast<unsigned long long>(e->frame), e->t[0], e->t[1], e->t[2], e->q[0], e->q[1], e->q[2],
                e->q[3], e->quality, std::string(p::to_string(e->status)).c_str());
    ++n;
  }
  run(c.request("Quit"));
  return 0;
}
