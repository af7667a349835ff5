// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <stop_token>
#include <thread>
#include <vector>

#include "v4r/pipeline/camera_image.hpp"
#include "v4r/pipeline/object_search.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief ObjectSearch on a worker thread of its own (issue 10: "a search never blocks the cycle
/// of objects that are tracking"), for `v4r serve`; `v4r track` and SingleObjectTracker keep the
/// synchronous ObjectSearch::update (offline, deterministic).
///
/// On the cycle's thread, per frame: apply() before VisionCycle::process sets the pose the worker
/// last found and confirmed on its object, if that object is still `searching` in the same search
/// (a SetPose, a removal or a new search meanwhile wins: the late result is dropped); update()
/// after it does the cheap bookkeeping (search_step: an object `lost` for search.lost_frames
/// frames turns `searching`) and, while an object is searching, copies camera 0's image (grey and
/// colour) into buffers kept between frames and offers it to the worker, replacing a frame the
/// worker has not taken yet: frames are never queued, the worker always takes the newest one.
/// The worker runs ObjectSearch::search_frame (candidate, tag, restarts, detector, refinement) for
/// each searching object on its copy; a candidate is confirmed on the next frame the worker
/// searches (consistency over 2 frames, as in ObjectSearch). It never touches the live scene:
/// the hand-over (images, per-object orders, results) is guarded by one mutex.
///
/// The cycle's thread allocates nothing once the image size and the objects are known; set_search
/// (a changed scene) allocates. Destruction requests a stop and joins the worker: a search under
/// way skips its hypotheses not yet refined (at most one detector run finishes first).
class BackgroundSearch {
 public:
  /// Test seam: called on the worker with its stop token after it took a frame, before it searches.
  using Hook = std::function<void(std::stop_token)>;

  explicit BackgroundSearch(const ObjectSearchParams& p, Hook hook = {});
  ~BackgroundSearch();
  BackgroundSearch(const BackgroundSearch&) = delete;
  BackgroundSearch& operator=(const BackgroundSearch&) = delete;

  /// Cycle's thread: the search set up (ObjectSearch::add_object) for the scene's `objects`
  /// current objects, in their order; it replaces the one before, whose frame not yet taken and
  /// results are dropped, and every object's bookkeeping starts afresh. Allocates.
  void set_search(std::unique_ptr<ObjectSearch> search, std::size_t objects);

  /// Cycle's thread, before VisionCycle::process: applies the worker's newest result (see the
  /// class comment). Returns the number of objects it set a pose on. After objects were added,
  /// removed or given another model, call set_search first (indices may have moved).
  int apply(scene::Scene& scene);

  /// Cycle's thread, after VisionCycle::process: bookkeeping, then the frame for the worker
  /// (only while an object is searching; `images[0]` is camera 0's).
  void update(scene::Scene& scene, std::span<const CameraImage> images, double stamp_s);

  /// Frames the worker searched to the end so far (thread-safe).
  [[nodiscard]] std::int64_t frames_searched() const { return frames_searched_.load(); }
  /// Poses apply() set so far (thread-safe).
  [[nodiscard]] std::int64_t poses_applied() const { return poses_applied_.load(); }
  /// Found poses apply() dropped because their object had been given a pose, removed or
  /// searched anew meanwhile (thread-safe).
  [[nodiscard]] std::int64_t results_dropped() const { return results_dropped_.load(); }

 private:
  struct Order {  // what the worker is to do with one object
    bool searching = false;
    std::uint64_t session = 0;  // one per search of the object (from its turning `searching`)
    bool have_last = false;
    LastSeen last;  // where it was last seen, camera 0's frame
  };
  struct Found {  // what the worker found for one object
    bool locked = false;
    std::uint64_t session = 0;
    geometry::SE3 T_cam_obj;
    double evidence = 0.0;
  };
  struct Frame {  // a copy of camera 0's image and the orders made on it
    std::vector<std::uint8_t> grey, colour;
    int width = 0, height = 0;
    bool has_colour = false;
    double stamp_s = 0.0;
    std::uint64_t generation = 0;
    std::vector<Order> orders;
  };

  void run(std::stop_token st);
  void search_frame(std::stop_token st);

  ObjectSearchParams p_;
  Hook hook_;

  // Cycle's thread only.
  std::uint64_t generation_ = 0;  // of the search last given to set_search
  std::vector<char> active_;      // searchable, per scene object
  std::vector<int> lost_streak_;
  std::vector<char> was_searching_;
  std::vector<std::uint64_t> session_;
  std::vector<char> have_last_;
  std::vector<LastSeen> last_;
  Frame staging_;                 // filled outside the lock, then swapped with pending_
  std::vector<Found> taken_;      // the result apply() took

  // Worker only.
  std::unique_ptr<ObjectSearch> search_;
  std::uint64_t search_generation_ = 0;
  std::vector<std::uint64_t> seen_session_;  // per object: the search session begun on search_
  Frame work_;
  std::vector<Found> found_;

  // Guarded by mutex_.
  std::mutex mutex_;
  std::condition_variable_any wake_;
  Frame pending_;
  bool pending_full_ = false;
  std::unique_ptr<ObjectSearch> next_search_;
  std::uint64_t next_generation_ = 0;
  std::vector<Found> result_;
  std::uint64_t result_generation_ = 0;
  bool result_full_ = false;

  std::atomic<std::int64_t> frames_searched_{0}, poses_applied_{0}, results_dropped_{0};
  std::uint64_t next_session_ = 0;
  std::jthread worker_;  // last: stopped and joined before the members above go
};

}  // namespace v4r::pipeline
