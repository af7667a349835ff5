// v4r - robust model-based object tracking. MIT licence.
#include "v4r/server/model_loading.hpp"

#include <cctype>
#include <cerrno>
#include <cstdlib>
#include <filesystem>

#include <fmt/format.h>
#include <unistd.h>

#include "v4r/core/log.hpp"
#include "v4r/model/cao_reader.hpp"
#include "v4r/model/mesh_reader.hpp"
#include "v4r/model/model_scale.hpp"

namespace v4r::server {

namespace fs = std::filesystem;

namespace {

Unexpected fail(std::string_view code, Error e) {
  // A refusal by the path policy (an include outside the data folders) keeps its code.
  if (e.field != protocol::code::kForbidden) e.field = std::string(code);
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

/// Reader options for a client's .cao: `load(...)` reads only inside the data folders.
model::CaoReadOptions cao_options(const PathPolicy& data) {
  model::CaoReadOptions o;
  o.include_check = [&data](const std::string& path) -> Expected<std::string> {
    auto r = data.resolve_read(path);
    if (!r) return r.error();
    return r->string();
  };
  return o;
}

/// A private temporary folder (mode 0700, unique name) holding one file, removed on destruction.
class PrivateTempFile {
 public:
  explicit PrivateTempFile(std::string_view extension) {
    std::string dir = (fs::temp_directory_path() / "v4r_serve_XXXXXX").string();
    if (!::mkdtemp(dir.data())) return;
    dir_ = dir;
    std::string file = (fs::path(dir_) / fmt::format("mesh_XXXXXX.{}", extension)).string();
    fd_ = ::mkstemps(file.data(), static_cast<int>(extension.size() + 1));
    if (fd_ >= 0) path_ = file;
  }
  ~PrivateTempFile() {
    if (fd_ >= 0) ::close(fd_);
    std::error_code ec;
    if (!dir_.empty()) fs::remove_all(dir_, ec);
  }
  PrivateTempFile(const PrivateTempFile&) = delete;
  PrivateTempFile& operator=(const PrivateTempFile&) = delete;

  [[nodiscard]] const std::string& path() const { return path_; }
  /// Writes all of `text` to the file and closes it; false on any failure.
  bool write_and_close(std::string_view text) {
    if (fd_ < 0) return false;
    std::size_t done = 0;
    while (done < text.size()) {
      const ssize_t n = ::write(fd_, text.data() + done, text.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      done += static_cast<std::size_t>(n);
    }
    const bool closed = ::close(fd_) == 0;
    fd_ = -1;
    return done == text.size() && closed;
  }

 private:
  std::string dir_, path_;
  int fd_ = -1;
};

}  // namespace

Expected<std::shared_ptr<const model::Model>> load_model_text(const std::string& text, protocol::ModelFormat format,
                                                              const std::string& source, const PathPolicy& data,
                                                              double scale) {
  if (format == protocol::ModelFormat::kCao)
    return finish(model::parse_cao(text, source, cao_options(data)), source, scale);
  // Meshes go through assimp, which reads files: write the payload to a file that only this
  // process can reach (mkstemp in a fresh mkdtemp folder), removed right after.
  PrivateTempFile tmp(protocol::to_string(format));
  if (!tmp.write_and_close(text)) return fail(protocol::code::kIoError, "cannot write a temporary file for the mesh");
  model::MeshImportOptions mo;
  mo.scale = scale;
  auto m = model::load_mesh(tmp.path(), mo);
  if (!m) {
    Error e = m.error();
    e.file = source;
    return fail(protocol::code::kBadModel, std::move(e));
  }
  return finish(std::move(m), source);
}

Expected<std::shared_ptr<const model::Model>> load_model_path(const std::string& path,
                                                              std::optional<protocol::ModelFormat> format,
                                                              const PathPolicy& data, double scale) {
  // The policy comes first: a path outside the data folders is refused before anything else is
  // said about it (not even whether it exists).
  auto resolved = data.resolve_read(path);
  if (!resolved) {
    Error e = resolved.error();
    return Unexpected{std::move(e)};
  }
  if (!format) format = format_of(path);
  if (!format)
    return fail(protocol::code::kUnsupported,
                fmt::format("{}: cannot tell the model format from the extension (use format=cao|obj|ply|stl)", path));
  if (*format == protocol::ModelFormat::kCao)
    return finish(model::load_cao(resolved->string(), cao_options(data)), path, scale);
  model::MeshImportOptions mo;
  mo.scale = scale;
  return finish(model::load_mesh(resolved->string(), mo), path);
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
      // A job that throws (a bug, out of memory) must not end the thread and every later job.
      try {
        job();
      } catch (const std::exception& e) {
        V4R_LOG_ERROR("v4r serve: background job failed: {}", e.what());
      } catch (...) {
        V4R_LOG_ERROR("v4r serve: background job failed: unknown exception");
      }
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
