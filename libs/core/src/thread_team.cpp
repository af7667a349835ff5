// v4r - robust model-based object tracking. MIT licence.
#include "v4r/core/thread_team.hpp"

#include <algorithm>

namespace v4r {

ThreadTeam::ThreadTeam(std::size_t size) {
  const std::size_t n = std::max<std::size_t>(1, size);
  threads_.reserve(n - 1);
  for (std::size_t m = 1; m < n; ++m) threads_.emplace_back([this, m] { serve(m); });
}

ThreadTeam::~ThreadTeam() {
  {
    std::scoped_lock lock(mutex_);
    stop_ = true;
  }
  start_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void ThreadTeam::work(std::size_t member) {
  for (std::size_t k = member; k < tasks_; k += size()) fn_(arg_, k, member);
}

void ThreadTeam::serve(std::size_t member) {
  std::uint64_t seen = 0;
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      start_.wait(lock, [&] { return stop_ || batch_ != seen; });
      if (stop_) return;
      seen = batch_;
    }
    work(member);
    bool last = false;
    {
      std::scoped_lock lock(mutex_);
      last = --pending_ == 0;
    }
    if (last) done_.notify_one();
  }
}

void ThreadTeam::run(std::size_t tasks, Task fn, void* arg) {
  if (threads_.empty() || tasks <= 1) {
    for (std::size_t k = 0; k < tasks; ++k) fn(arg, k, 0);
    return;
  }
  {
    std::scoped_lock lock(mutex_);
    tasks_ = tasks;
    fn_ = fn;
    arg_ = arg;
    pending_ = threads_.size();
    ++batch_;
  }
  start_.notify_all();
  work(0);
  std::unique_lock lock(mutex_);
  done_.wait(lock, [&] { return pending_ == 0; });
}

}  // namespace v4r
