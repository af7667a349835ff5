// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

namespace v4r {

/// \brief A fixed team of threads that runs a batch of tasks and waits for all of them: the
/// calling thread is member 0, size() - 1 threads wait in the background between batches.
///
/// Task k of a batch always runs on member k % size(), so a member's scratch state (indexed by
/// the member number handed to the task) is used by one thread at a time, and the split of work
/// does not depend on timing. run() allocates nothing, prints nothing and throws nothing (a task
/// must not throw); it must not be called from inside a task or from two threads at once. The
/// threads are started by the constructor and joined by the destructor.
class ThreadTeam {
 public:
  /// A task: `arg` as given to run(), the task's number and the member running it.
  using Task = void (*)(void* arg, std::size_t task, std::size_t member);

  explicit ThreadTeam(std::size_t size);
  ~ThreadTeam();
  ThreadTeam(const ThreadTeam&) = delete;
  ThreadTeam& operator=(const ThreadTeam&) = delete;

  [[nodiscard]] std::size_t size() const { return threads_.size() + 1; }
  /// Runs tasks 0 .. tasks-1 (task k on member k % size()) and returns when all have finished.
  void run(std::size_t tasks, Task fn, void* arg);

 private:
  void serve(std::size_t member);
  void work(std::size_t member);

  std::mutex mutex_;
  std::condition_variable start_, done_;
  std::vector<std::thread> threads_;
  std::uint64_t batch_ = 0;    // number of the current batch
  std::size_t pending_ = 0;    // background members still working on it
  bool stop_ = false;
  std::size_t tasks_ = 0;
  Task fn_ = nullptr;
  void* arg_ = nullptr;
};

}  // namespace v4r
