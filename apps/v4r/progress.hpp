// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <unistd.h>

#include <chrono>
#include <cstdio>

#include <fmt/format.h>

namespace v4r::app {

/// True when stderr is a terminal (the progress line is shown there only, unless forced).
inline bool stderr_is_terminal() { return ::isatty(STDERR_FILENO) != 0; }

/// \brief The progress line on stderr of a run that takes more than a second: frames done (of
/// the total when known), rate and, for tracking, frames lost so far; rewritten in place at most
/// four times a second and ended with a newline.
class ProgressLine {
 public:
  ProgressLine(bool on, int total) : on_(on), total_(total), start_(Clock::now()), last_(start_) {}
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;
  ~ProgressLine() { finish(); }

  /// `lost` < 0: not shown.
  void update(int frames, int lost = -1) {
    if (!on_) return;
    const auto now = Clock::now();
    if (now - start_ < std::chrono::seconds(1) || now - last_ < std::chrono::milliseconds(250)) return;
    last_ = now;
    shown_ = true;
    const double s = std::chrono::duration<double>(now - start_).count();
    const std::string of = total_ > 0 ? fmt::format("/{}", total_) : "";
    const std::string lost_text = lost >= 0 ? fmt::format("  lost {}", lost) : "";
    fmt::print(stderr, "\r  frame {}{}  {:.0f} fps{}   ", frames, of, frames / s, lost_text);
    std::fflush(stderr);
  }
  void finish() {
    if (shown_) fmt::print(stderr, "\n");
    shown_ = false;
  }

 private:
  using Clock = std::chrono::steady_clock;
  bool on_;
  int total_;
  Clock::time_point start_, last_;
  bool shown_ = false;
};

}  // namespace v4r::app
