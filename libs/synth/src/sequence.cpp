// v4r - robust model-based object tracking. MIT licence.
#include <algorithm>
#include <exception>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "v4r/io/camera_io.hpp"
#include "v4r/io/pose_io.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/synth/renderer.hpp"

namespace v4r::synth {
namespace {

namespace fs = std::filesystem;

Unexpected path_error(const fs::path& p, const std::string& message) {
  return Unexpected{Error{message, p.string(), 0, 0, {}}};
}

Expected<void> create_dir(const fs::path& p) {
  std::error_code ec;
  fs::create_directories(p, ec);
  if (ec || !fs::is_directory(p, ec)) {
    return path_error(p, fmt::format("cannot create directory{}", ec ? ": " + ec.message() : std::string{}));
  }
  return {};
}

/// Removes frames/NNNNNN.png files (six digits) with an index >= `count`.
Expected<void> remove_stale_frames(const fs::path& frames, std::size_t count) {
  std::error_code ec;
  for (fs::directory_iterator it(frames, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() != 10 || name.substr(6) != ".png" ||
        !std::all_of(name.begin(), name.begin() + 6, [](char c) { return c >= '0' && c <= '9'; }))
      continue;
    if (static_cast<std::size_t>(std::stoul(name.substr(0, 6))) < count) continue;
    std::error_code rm;
    if (!fs::remove(it->path(), rm) || rm)
      return path_error(it->path(), "cannot remove a stale frame of an earlier sequence");
  }
  if (ec) return path_error(frames, fmt::format("cannot list the directory: {}", ec.message()));
  return {};
}

}  // namespace

Expected<void> write_sequence(const std::string& dir, const std::string& model_cao, const geometry::PinholeCamera& cam,
                              const std::vector<geometry::SE3>& trajectory, const RenderOptions& opt) {
  // Validate everything before writing anything.
  auto model = model::parse_cao(model_cao, (fs::path(dir) / "model.cao").string());
  if (!model) return model.error();
  return write_sequence(dir, *model, "model.cao", model_cao, cam, trajectory, opt);
}

Expected<void> write_sequence(const std::string& dir, const model::Model& model, const std::string& model_file,
                              const std::string& model_bytes, const geometry::PinholeCamera& cam,
                              const std::vector<geometry::SE3>& trajectory, const RenderOptions& opt,
                              const std::function<void(std::size_t, std::size_t)>& progress) {
  const fs::path root(dir);
  const fs::path model_path = root / model_file;
  if (trajectory.empty()) return path_error(root, "the trajectory is empty: nothing to render");
  if (cam.width <= 0 || cam.height <= 0 || !(cam.fx > 0) || !(cam.fy > 0))
    return path_error(root, fmt::format("invalid camera ({}x{}, fx={}, fy={})", cam.width, cam.height, cam.fx, cam.fy));

  if (auto r = create_dir(root / "frames"); !r) return r;
  {
    std::ofstream f(model_path, std::ios::binary);
    f << model_bytes;
    if (!f) return path_error(model_path, "cannot write the model");
  }
  if (auto r = io::save_camera_opencv((root / "camera.yaml").string(), cam); !r) return r;
  if (auto r = io::save_pose_file((root / "init_pose.txt").string(), trajectory.front()); !r) return r;
  std::vector<io::PoseRow> rows;
  rows.reserve(trajectory.size());
  for (std::size_t i = 0; i < trajectory.size(); ++i) rows.push_back(io::PoseRow{static_cast<int>(i), trajectory[i]});
  if (auto r = io::save_pose_csv((root / "gt.csv").string(), rows); !r) return r;

  // Frames of an earlier, longer sequence in the same directory would be read as part of this one.
  if (auto r = remove_stale_frames(root / "frames", trajectory.size()); !r) return r;

  RenderOptions o = opt;
  if (o.cycle_frames <= 0) o.cycle_frames = static_cast<int>(trajectory.size());
  Renderer renderer(cam, o);
  renderer.set_scene_reference(model, trajectory);
  // Motion blur needs the pose before frame 0: extrapolated with constant velocity.
  const geometry::SE3 before_first =
      trajectory.size() > 1 ? trajectory[0] * trajectory[1].inverse() * trajectory[0] : trajectory[0];
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const fs::path frame_path = root / "frames" / fmt::format("{:06d}.png", i);
    const geometry::SE3* prev = i > 0 ? &trajectory[i - 1] : &before_first;
    const cv::Mat img = renderer.render(model, trajectory[i], static_cast<int>(i), prev);
    bool ok = false;
    try {
      ok = cv::imwrite(frame_path.string(), img);
    } catch (const std::exception& e) {
      return path_error(frame_path, fmt::format("cannot write the frame: {}", e.what()));
    }
    if (!ok) return path_error(frame_path, "cannot write the frame");
    if (progress) progress(i + 1, trajectory.size());
  }
  return {};
}

}  // namespace v4r::synth
