// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "v4r/detection/tag_spec.hpp"
#include "v4r/detection/template_set.hpp"
#include "v4r/pipeline/background_search.hpp"
#include "v4r/pipeline/object_search.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::server {

/// \brief The search of `v4r serve` (issue 10): objects without a pose (no SetPose yet) and objects
/// lost for search.lost_frames frames are searched for by a pipeline::ObjectSearch. With
/// search.background (the default) the search runs on a worker thread with the newest frame
/// (pipeline::BackgroundSearch) and only its bookkeeping on the tracking thread, so that the
/// tracked objects' cycles keep their budget; without it, on the tracking thread after each
/// cycle, as `v4r track` does. The detector's templates of a model whose object is
/// searching or lost are loaded or built (detection::load_or_build, cached) on a builder thread
/// of their own, so that the frames never wait for them; the object is searched once they are
/// there (an object that tracks well costs no templates).
/// update() allocates only when the scene's models changed or templates arrived.
class ServiceSearch {
 public:
  ServiceSearch(const pipeline::CycleParams& cycle, const pipeline::ObjectSearchParams& sp,
                const detection::DetectorParams& dp, const geometry::PinholeCamera& cam, std::string cache_dir,
                pipeline::BackgroundSearch::Hook worker_hook = {});
  ~ServiceSearch();
  ServiceSearch(const ServiceSearch&) = delete;
  ServiceSearch& operator=(const ServiceSearch&) = delete;

  /// Before the frame's cycle, on the tracking thread: a pose the worker found is set on its
  /// object if it is still searching (background search only).
  void before_cycle(scene::Scene& scene);
  /// After the frame's cycle, on the tracking thread.
  void update(scene::Scene& scene, std::span<const pipeline::CameraImage> images, double stamp_s);
  /// The object named `name` (now or when added later) has this AprilTag: its search starts from
  /// the tag (pipeline::ObjectSearch::set_tag_start, camera 0). Before the first update().
  void set_tag(const std::string& name, const detection::TagSpec& tag) { tags_[name] = tag; }
  /// Templates of `model` are ready (or could not be built); for tests.
  [[nodiscard]] bool ready(const model::Model* model) const;
  /// The worker's search (null without search.background); for tests and benchmarks.
  [[nodiscard]] const pipeline::BackgroundSearch* background() const { return background_.get(); }

 private:
  struct Entry {
    std::shared_ptr<const model::Model> model;  // kept alive: the key's address is not reused
    std::shared_ptr<const detection::TemplateSet> templates;  // null: pending or failed
    bool done = false;
  };
  void build_loop(std::stop_token st);
  /// Templates asked for and taken; a new search when the scene's objects or templates changed.
  void refresh(scene::Scene& scene);

  pipeline::CycleParams cycle_;
  pipeline::ObjectSearchParams sp_;
  detection::DetectorParams dp_;
  geometry::PinholeCamera cam_;
  std::string cache_dir_;
  std::map<const model::Model*, Entry> entries_;  // tracking thread only
  std::vector<const model::Model*> searched_;     // scene object models the search was set up for
  std::vector<std::string> searched_names_;       // ... and their names
  std::map<std::string, detection::TagSpec> tags_;  // object name -> its tag (set_tag)
  std::unique_ptr<pipeline::ObjectSearch> search_;  // on the tracking thread (not search.background)
  std::unique_ptr<pipeline::BackgroundSearch> background_;  // search.background

  mutable std::mutex mutex_;  // guards jobs_, finished_, ready_
  std::condition_variable_any wake_;
  std::deque<std::shared_ptr<const model::Model>> jobs_;
  std::vector<std::pair<const model::Model*, std::shared_ptr<const detection::TemplateSet>>> finished_;
  std::vector<const model::Model*> ready_;
  std::jthread builder_;
};

}  // namespace v4r::server
