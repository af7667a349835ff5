// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <chrono>

namespace v4r {

/// \brief Monotonic clock used for cycle timing and budgets.
using Clock = std::chrono::steady_clock;

/// Milliseconds elapsed between two time points, as double.
inline double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace v4r
