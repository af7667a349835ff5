// v4r - robust model-based object tracking. MIT licence.
// The test binary's counting global allocator (defined once, in detector_test.cpp): while
// `counting` is set, every operator new adds one to `allocations`.
#pragma once

#include <atomic>

namespace alloc_count {
extern std::atomic<bool> counting;
extern std::atomic<long> allocations;
}  // namespace alloc_count

// The short names the tests use.
inline std::atomic<bool>& g_counting = alloc_count::counting;
inline std::atomic<long>& g_allocations = alloc_count::allocations;
