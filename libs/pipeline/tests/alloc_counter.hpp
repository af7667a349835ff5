// v4r - robust model-based object tracking. MIT licence.
// The pipeline tests' counting allocator (operator new is replaced in cycle_test.cpp): while
// g_counting is set, every heap allocation of any thread adds one to g_allocations.
#pragma once
#include <atomic>

namespace v4r::test {
extern std::atomic<bool> g_counting;
extern std::atomic<long> g_allocations;
}  // namespace v4r::test
