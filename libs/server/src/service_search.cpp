// v4r - robust model-based object tracking. MIT licence.
#include "v4r/server/service_search.hpp"

#include <algorithm>

#include "v4r/core/log.hpp"
#include "v4r/detection/tag_start.hpp"
#include "v4r/detection/template_cache.hpp"

namespace v4r::server {

ServiceSearch::ServiceSearch(const pipeline::CycleParams& cycle, const pipeline::ObjectSearchParams& sp,
                             const detection::DetectorParams& dp, const geometry::PinholeCamera& cam,
                             std::string cache_dir, pipeline::BackgroundSearch::Hook worker_hook)
    : cycle_(cycle), sp_(sp), dp_(dp), cam_(cam), cache_dir_(std::move(cache_dir)) {
  if (sp_.background) background_ = std::make_unique<pipeline::BackgroundSearch>(sp_, std::move(worker_hook));
  builder_ = std::jthread([this](std::stop_token st) { build_loop(st); });
}

ServiceSearch::~ServiceSearch() {
  builder_.request_stop();
  wake_.notify_all();
}

bool ServiceSearch::ready(const model::Model* model) const {
  std::scoped_lock lock(mutex_);
  return std::find(ready_.begin(), ready_.end(), model) != ready_.end();
}

void ServiceSearch::build_loop(std::stop_token st) {
  for (;;) {
    std::shared_ptr<const model::Model> m;
    {
      std::unique_lock lock(mutex_);
      if (!wake_.wait(lock, st, [&] { return !jobs_.empty(); })) return;
      m = std::move(jobs_.front());
      jobs_.pop_front();
    }
    std::shared_ptr<const detection::TemplateSet> ts;
    struct Stopped {};
    try {
      detection::CacheReport rep;
      // A stop request (the server shutting down) abandons a build at the next view.
      auto r = detection::load_or_build(*m, cam_, dp_, cache_dir_, &rep, [&st](std::size_t, std::size_t) {
        if (st.stop_requested()) throw Stopped{};
      });
      if (r) {
        ts = *r;
        if (rep.built) V4R_LOG_INFO("v4r serve: built the detector's templates of model '{}' ({})", m->name(), rep.reason);
      } else {
        V4R_LOG_ERROR("v4r serve: model '{}' cannot be searched for: {}", m->name(), r.error().to_string());
      }
    } catch (const Stopped&) {
      return;
    } catch (const std::exception& e) {
      V4R_LOG_ERROR("v4r serve: model '{}' cannot be searched for: {}", m->name(), e.what());
    }
    std::scoped_lock lock(mutex_);
    finished_.emplace_back(m.get(), std::move(ts));
    ready_.push_back(m.get());
  }
}

void ServiceSearch::before_cycle(scene::Scene& scene) {
  if (!background_) return;
  // A command since the last frame may have removed or replaced objects (their indices shift):
  // a new search first, so that the worker's result for the objects before is dropped.
  refresh(scene);
  background_->apply(scene);
}

void ServiceSearch::update(scene::Scene& scene, std::span<const pipeline::CameraImage> images, double stamp_s) {
  refresh(scene);
  if (background_) {
    background_->update(scene, images, stamp_s);
  } else if (search_) {
    search_->update(scene, images, stamp_s);
  }
}

void ServiceSearch::refresh(scene::Scene& scene) {
  const auto objs = scene.objects();
  bool changed = objs.size() != searched_.size();
  for (std::size_t i = 0; i < objs.size(); ++i) {
    const model::Model* m = objs[i].model.get();
    if (!changed && (searched_[i] != m || searched_names_[i] != objs[i].name)) changed = true;
    // A model whose object needs searching gets its templates built on the builder thread (the
    // objects that track well cost no templates and no memory).
    const bool wanted = objs[i].status == scene::TrackStatus::kSearching || objs[i].status == scene::TrackStatus::kLost;
    if (m && wanted && !entries_.contains(m)) {
      entries_[m].model = objs[i].model;
      std::scoped_lock lock(mutex_);
      jobs_.push_back(objs[i].model);
      wake_.notify_all();
    }
  }
  {
    std::scoped_lock lock(mutex_);
    for (auto& [m, ts] : finished_) {
      auto it = entries_.find(m);
      if (it == entries_.end()) continue;
      it->second.templates = std::move(ts);
      it->second.done = true;
      changed = true;
    }
    finished_.clear();
  }
  if (changed) {
    // The scene's objects (or their templates) changed: a new search over the current objects.
    auto search = std::make_unique<pipeline::ObjectSearch>(cycle_, sp_, dp_);
    searched_.resize(objs.size());
    searched_names_.resize(objs.size());
    for (std::size_t i = 0; i < objs.size(); ++i) {
      searched_[i] = objs[i].model.get();
      searched_names_[i] = objs[i].name;
      const auto it = entries_.find(searched_[i]);
      if (it == entries_.end() || !it->second.templates) continue;
      search->add_object(scene, i, it->second.templates);
      if (const auto tag = tags_.find(objs[i].name); tag != tags_.end()) {
        auto start = detection::TagStart::create(tag->second, cam_, sp_.tag);
        if (start) {
          search->set_tag_start(i, std::move(*start));
        } else {
          V4R_LOG_ERROR("v4r serve: the tag of object '{}' is not used: {}", objs[i].name, start.error().to_string());
        }
      }
    }
    if (background_) {
      background_->set_search(std::move(search), objs.size());  // results for the objects before are dropped
    } else {
      search_ = std::move(search);
    }
  }
}

}  // namespace v4r::server
