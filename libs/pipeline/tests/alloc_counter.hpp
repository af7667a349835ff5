// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <atomic>

namespace v4r::test {

/// The pipeline tests' counting global allocator (defined with operator new in cycle_test.cpp):
/// allocations on any thread are counted while g_counting is set.
extern std::atomic<bool> g_counting;
extern std::atomic<long> g_allocations;

}  // namespace v4r::test
