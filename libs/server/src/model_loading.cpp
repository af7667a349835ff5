// v4r - robust model-based object tracking. MIT licence.
#include "v4r/server/model_loading.hpp"

#include <atomic>
#include <cctype>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>
#include <unistd.h>

#include "v4r/model/cao_reader.hpp"
#include "v4r/model/mesh_reader.hpp"
#include "v4r/model/model_scale.hpp"

namespace v4r::server {

namespace fs = std::filesystem;

namespace {

Unexpected fail(std::string_view code, Error e) {
  e.field = std::string(code);
  return Unexpected{std::move(e)};
}

Unexpected fail(std::string_view code, std::string msg) { return fail(code, Error{std::move(msg), {}, 0, 0, {}}); }

Expected<std::shared_ptr<const model::Model>> finish(Expected<model::Model> m, const std::string& source,
                                                     double scale = 1.0) {
  if (!m) return fail(protocol::code::kBadModel, m.error());
  if (scale != 1.0) {  // .cao in other units than metres (meshes are scaled on import)
    m = model::scaled(*m, scale);
    if (!m) return fail(protocol::code::kBadModel, m.error());
  }
  if (m->lines().empty() && m->arcs().empty()) return fail(protocol::code::kBadModel, source + ": model has no edges to track");
  return std::shared_ptr<const model::Model>(std::make_shared<const model::Model>(std::move(*m)));
}

std::optional<protocol::ModelFormat> format_of(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".cao") return protocol::ModelFormat::kCao;
  if (ext == ".obj") return protocol::ModelFormat::kObj;
  if (ext == ".ply") return protocol::ModelFormat::kPly;
  if (ext == ".stl") return protocol::ModelFormat::kStl;
  return std::nullopt;
}

}  // namespace

Expected<std::shared_ptr<const model::Model>> load_model_text(const std::string& text, protocol::ModelFormat format,
                                                              const std::string& source, double scale) {
  if (format == protocol::ModelFormat::kCao) return finish(model::parse_cao(text, source), source, scale);
  // Meshes go through assimp, which reads files: write the payload to a private temporary file.
  static std::atomic<unsigned> counter{0};
  const fs::path tmp = fs::temp_directory_path() /
                       fmt::format("v4r_serve_{}_{}.{}", ::getpid(), counter++, protocol::to_string(format));
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) return fail(protocol::code::kIoError, "cannot write a temporary file for the mesh");
  const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  std::fclose(f);
  if (!ok) {
    std::error_code ec;
    fs::remove(tmp, ec);
    return fail(protocol::code::kIoError, "cannot write a temporary file for the mesh");
  }
  model::MeshImportOptions mo;
  mo.scale = scale;
  auto m = model::load_mesh(tmp.string(), mo);
  std::error_code ec;
  fs::remove(tmp, ec);
  if (!m) {
    Error e = m.error();
    e.file = source;
    return fail(protocol::code::kBadModel, std::move(e));
  }
  return finish(std::move(m), source);
}

Expected<std::shared_ptr<const model::Model>> load_model_path(const std::string& path,
                                                              std::optional<protocol::ModelFormat> format,
                                                              double scale) {
  if (!format) format = format_of(path);
  if (!format)
    return fail(protocol::code::kUnsupported,
                fmt::format("{}: cannot tell the model format from the extension (use format=cao|obj|ply|stl)", path));
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return fail(protocol::code::kIoError, fmt::format("{}: no such model file", path));
  if (*format == protocol::ModelFormat::kCao) return finish(model::load_cao(path), path, scale);
  model::MeshImportOptions mo;
  mo.scale = scale;
  return finish(model::load_mesh(path, mo), path);
}

Worker::Worker() {
  thread_ = std::jthread([this](std::stop_token st) {
    for (;;) {
      std::function<void()> job;
      {
        std::unique_lock lock(mutex_);
        if (!wake_.wait(lock, st, [&] { return !jobs_.empty(); })) return;
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
      job();
    }
  });
}

Worker::~Worker() { stop(); }

void Worker::post(std::function<void()> job) {
  {
    std::scoped_lock lock(mutex_);
    jobs_.push_back(std::move(job));
  }
  wake_.notify_one();
}

void Worker::stop() {
  if (!thread_.joinable()) return;
  thread_.request_stop();
  thread_.join();
  std::scoped_lock lock(mutex_);
  jobs_.clear();
}

}  // namespace v4r::server
