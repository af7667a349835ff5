// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace v4r::pipeline {

/// \brief What a measurement unit needs to know about the cycle it runs in, and what it counts
/// for the cycle's report and budget.
struct MeasureContext {
  std::int64_t frame = 0;   ///< cycle number (spreads the search back-off over frames)
  bool first_pass = true;   ///< the first track + solve pass of this frame: every feature is measured
  int search_level = 0;     ///< 0: normal windows; > 0: wider search after bad frames
  int degrade_level = 0;    ///< budget: 0 none, >= 1 fewer samples per feature
  int samples_per_circle = 64;  ///< budget: ellipse tracking lines beyond this take every other one
  // Counters (added to).
  long samples = 0;   ///< window rows / ellipse samples measured
  int windows = 0;    ///< windows measured
  int refound = 0;    ///< features missed in the first pass and found by a later one
  std::vector<Eigen::Vector2d>* edgels = nullptr;  ///< edge pixels for overlays (grows only up to its capacity)

  /// Search back-off (CycleParams::search_backoff_frames, _period): on the first pass at the
  /// normal level, a feature missed for `backoff_frames` frames or more waits its turn, spread
  /// over the frames by its index in the view (lines first, then arcs).
  [[nodiscard]] bool backing_off(int frames_missing, std::size_t index, int backoff_frames, int backoff_period) const {
    return first_pass && search_level == 0 && backoff_frames > 0 && frames_missing >= backoff_frames &&
           (frame + static_cast<std::int64_t>(index)) % std::max(1, backoff_period) != 0;
  }
};

}  // namespace v4r::pipeline
