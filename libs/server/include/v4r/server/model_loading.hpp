// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "v4r/core/expected.hpp"
#include "v4r/model/model.hpp"
#include "v4r/protocol/protocol.hpp"
#include "v4r/server/path_policy.hpp"

namespace v4r::server {

/// Parses the model text of `AddModel ... bytes=N` (.cao directly; OBJ/PLY/STL through a
/// temporary file made with mkstemp in a private mkdtemp folder and removed after use). `source`
/// names it in errors; `load(...)` includes of a .cao read only inside `data`. Errors set
/// `Error::field` to the protocol error code (bad_model, unsupported, io_error, forbidden). A
/// model without edges or circles is an error. Every length is multiplied by `scale` (model units
/// to metres, AddModel scale=).
Expected<std::shared_ptr<const model::Model>> load_model_text(const std::string& text, protocol::ModelFormat format,
                                                              const std::string& source, const PathPolicy& data,
                                                              double scale = 1.0);

/// Loads the model file of `AddModel ... path=FILE`: the path (and every `load(...)` include) must
/// resolve inside `data`, or the request is refused with `forbidden` before anything is read;
/// without a format it is deduced from the extension. Errors as load_model_text.
Expected<std::shared_ptr<const model::Model>> load_model_path(const std::string& path,
                                                              std::optional<protocol::ModelFormat> format,
                                                              const PathPolicy& data, double scale = 1.0);

/// \brief One background thread running queued jobs in order (model parsing, so that neither the
/// network thread nor the tracking thread waits for a large model). Jobs still queued at
/// destruction are dropped; the running one is finished.
class Worker {
 public:
  Worker();
  ~Worker();
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;
  /// Queues a job (thread-safe).
  void post(std::function<void()> job);
  /// Stops after the running job and joins.
  void stop();

 private:
  std::mutex mutex_;
  std::condition_variable_any wake_;
  std::deque<std::function<void()>> jobs_;
  std::jthread thread_;
};

}  // namespace v4r::server
