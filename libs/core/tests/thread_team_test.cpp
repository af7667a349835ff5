// v4r - robust model-based object tracking. MIT licence.
#include <atomic>
#include <set>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "v4r/core/thread_team.hpp"

namespace {

struct Record {
  std::vector<int> runs;                    // per task: how often it ran
  std::vector<std::size_t> member;          // per task: the member that ran it
  std::vector<std::thread::id> thread;      // per task: the thread that ran it
};

void record(void* arg, std::size_t task, std::size_t member) {
  auto& r = *static_cast<Record*>(arg);
  ++r.runs[task];
  r.member[task] = member;
  r.thread[task] = std::this_thread::get_id();
}

}  // namespace

TEST(ThreadTeam, EveryTaskRunsOnceOnMemberTaskModuloSizeAndBatchesRepeat) {
  v4r::ThreadTeam team(3);
  ASSERT_EQ(team.size(), 3u);
  for (int batch = 0; batch < 50; ++batch) {
    const std::size_t tasks = 1 + static_cast<std::size_t>(batch % 8);
    Record r{std::vector<int>(tasks, 0), std::vector<std::size_t>(tasks, 99), std::vector<std::thread::id>(tasks)};
    team.run(tasks, &record, &r);
    std::set<std::thread::id> threads;
    for (std::size_t k = 0; k < tasks; ++k) {
      EXPECT_EQ(r.runs[k], 1) << "batch " << batch << " task " << k;
      EXPECT_EQ(r.member[k], k % 3);
      if (r.member[k] == 0) {
        EXPECT_EQ(r.thread[k], std::this_thread::get_id());  // the caller is member 0
      }
      threads.insert(r.thread[k]);
    }
    EXPECT_EQ(threads.size(), std::min<std::size_t>(tasks, 3));  // one thread per member
  }
}

TEST(ThreadTeam, OneMemberRunsEverythingOnTheCallerAndZeroTasksReturn) {
  v4r::ThreadTeam team(1);
  EXPECT_EQ(team.size(), 1u);
  Record r{std::vector<int>(5, 0), std::vector<std::size_t>(5, 99), std::vector<std::thread::id>(5)};
  team.run(5, &record, &r);
  for (std::size_t k = 0; k < 5; ++k) {
    EXPECT_EQ(r.runs[k], 1);
    EXPECT_EQ(r.thread[k], std::this_thread::get_id());
  }
  v4r::ThreadTeam two(2);
  two.run(0, &record, nullptr);  // nothing to run: must not touch arg
}
