// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/background_search.hpp"

#include <algorithm>
#include <cstring>
#include <utility>

namespace v4r::pipeline {

namespace {

/// Copies a view's rows into `buf` (tightly packed, `bytes_per_pixel` per pixel); allocates only
/// when the image grew.
void copy_rows(const std::uint8_t* data, int width, int height, int stride, int bytes_per_pixel,
               std::vector<std::uint8_t>& buf) {
  const std::size_t row = static_cast<std::size_t>(width) * static_cast<std::size_t>(bytes_per_pixel);
  const std::size_t n = row * static_cast<std::size_t>(height);
  if (buf.size() < n) buf.resize(n);
  for (int y = 0; y < height; ++y)
    std::memcpy(buf.data() + row * static_cast<std::size_t>(y), data + static_cast<std::ptrdiff_t>(y) * stride, row);
}

}  // namespace

BackgroundSearch::BackgroundSearch(const ObjectSearchParams& p, Hook hook) : p_(p), hook_(std::move(hook)) {
  worker_ = std::jthread([this](std::stop_token st) { run(st); });
}

BackgroundSearch::~BackgroundSearch() {
  worker_.request_stop();  // wakes the worker's wait, and cuts a search under way short
  if (worker_.joinable()) worker_.join();
}

void BackgroundSearch::set_search(std::unique_ptr<ObjectSearch> search, std::size_t objects) {
  ++generation_;
  active_.assign(objects, 0);
  for (std::size_t i = 0; i < objects; ++i) active_[i] = search && search->searchable(i) ? 1 : 0;
  lost_streak_.assign(objects, 0);
  was_searching_.assign(objects, 0);
  session_.assign(objects, 0);
  have_last_.assign(objects, 0);
  last_.assign(objects, LastSeen{});
  std::unique_ptr<ObjectSearch> replaced;
  {
    std::scoped_lock lock(mutex_);
    replaced = std::move(next_search_);  // one the worker never took
    next_search_ = std::move(search);
    next_generation_ = generation_;
    pending_full_ = false;  // a frame ordered for the objects before
  }
}

int BackgroundSearch::apply(scene::Scene& scene) {
  std::uint64_t generation = 0;
  {
    std::scoped_lock lock(mutex_);
    if (!result_full_) return 0;
    std::swap(result_, taken_);
    generation = result_generation_;
    result_full_ = false;
  }
  wake_.notify_all();  // the worker may wait for the result slot to take the next frame
  const auto objs = scene.objects();
  // A result for the objects of an earlier search, or objects added or removed without
  // set_search (indices may have moved): none of it is used.
  if (generation != generation_ || objs.size() != active_.size()) {
    results_dropped_ += std::count_if(taken_.begin(), taken_.end(), [](const Found& f) { return f.locked; });
    return 0;
  }
  int applied = 0;
  for (std::size_t i = 0; i < taken_.size(); ++i) {
    const Found& f = taken_[i];
    if (!f.locked) continue;
    // Only for an object still searching in the same search: a SetPose, a removal (a new
    // generation) or a loss and a new search since the worker took its frame win.
    if (i >= objs.size() || i >= active_.size() || !active_[i] || objs[i].status != scene::TrackStatus::kSearching ||
        session_[i] != f.session) {
      ++results_dropped_;
      continue;
    }
    set_found_pose(scene, i, f.T_cam_obj, f.evidence);
    ++applied;
  }
  poses_applied_ += applied;
  return applied;
}

void BackgroundSearch::update(scene::Scene& scene, std::span<const CameraImage> images, double stamp_s) {
  const auto objs = scene.objects();
  const std::size_t n = std::min(objs.size(), active_.size());
  bool any = false;
  for (std::size_t i = 0; i < n; ++i) {
    if (!active_[i]) continue;
    LastSeen last;
    const SearchStep step = search_step(p_, scene, i, lost_streak_[i], last);
    const bool searching = objs[i].status == scene::TrackStatus::kSearching;
    if (searching && !was_searching_[i]) {
      // A new search: after a loss from the pose it was lost at, else (added without a pose) from none.
      session_[i] = ++next_session_;
      have_last_[i] = step == SearchStep::kStarted ? 1 : 0;
      if (have_last_[i]) last_[i] = last;
    }
    was_searching_[i] = searching ? 1 : 0;
    any = any || searching;
  }
  if (!any || images.empty() || images[0].grey.empty()) return;
  // The frame for the worker: copied outside the lock, then swapped in for a frame not yet taken.
  const CameraImage& img = images[0];
  Frame& f = staging_;
  f.width = img.grey.width;
  f.height = img.grey.height;
  copy_rows(img.grey.data, img.grey.width, img.grey.height, img.grey.stride, 1, f.grey);
  f.has_colour = !img.colour.empty() && img.colour.width == img.grey.width && img.colour.height == img.grey.height;
  if (f.has_colour) copy_rows(img.colour.data, img.colour.width, img.colour.height, img.colour.stride, 3, f.colour);
  f.stamp_s = stamp_s;
  f.generation = generation_;
  f.orders.resize(active_.size());  // (the frames' buffers circulate: one may come from before a change)
  for (std::size_t i = 0; i < f.orders.size(); ++i) {
    Order& o = f.orders[i];
    o.searching = i < n && active_[i] && was_searching_[i];
    o.session = i < session_.size() ? session_[i] : 0;
    o.have_last = i < have_last_.size() && have_last_[i];
    if (o.have_last) o.last = last_[i];
  }
  {
    std::scoped_lock lock(mutex_);
    std::swap(pending_, staging_);
    pending_full_ = true;
  }
  wake_.notify_all();
}

void BackgroundSearch::run(std::stop_token st) {
  for (;;) {
    std::unique_ptr<ObjectSearch> retired;
    {
      std::unique_lock lock(mutex_);
      // The newest frame, once apply() took the last result (one result in flight at most).
      if (!wake_.wait(lock, st, [&] { return pending_full_ && !result_full_; })) return;
      std::swap(pending_, work_);
      pending_full_ = false;
      if (next_search_) {
        retired = std::move(search_);
        search_ = std::move(next_search_);
        search_generation_ = next_generation_;
        seen_session_.clear();  // its objects' searches begin afresh
      }
    }
    retired.reset();  // (its templates and buffers are freed here, not on the cycle's thread)
    if (hook_) hook_(st);
    if (st.stop_requested()) return;
    if (!search_ || work_.generation != search_generation_) continue;
    search_frame(st);
    if (st.stop_requested()) return;
    {
      std::scoped_lock lock(mutex_);
      result_.assign(found_.begin(), found_.end());
      result_generation_ = work_.generation;
      result_full_ = true;
    }
    ++frames_searched_;
  }
}

void BackgroundSearch::search_frame(std::stop_token st) {
  const Frame& f = work_;
  const int w = f.width, h = f.height;
  CameraImage img;
  img.grey = image::ImageView{f.grey.data(), w, h, w};
  if (f.has_colour) img.colour = image::ColourView{f.colour.data(), w, h, 3 * w};
  if (seen_session_.size() != f.orders.size()) seen_session_.assign(f.orders.size(), 0);
  found_.resize(f.orders.size());
  for (std::size_t i = 0; i < f.orders.size(); ++i) {
    const Order& o = f.orders[i];
    found_[i] = Found{};
    if (!search_->searchable(i)) continue;
    if (!o.searching) {
      search_->end_search(i);
      continue;
    }
    if (seen_session_[i] != o.session) {  // a search begun since the worker's last frame
      seen_session_[i] = o.session;
      search_->begin_search(i, o.have_last ? &o.last : nullptr);
    }
    geometry::SE3 T;
    const SearchReport rep = search_->search_frame(i, img, f.stamp_s, T, st);
    if (rep.locked) found_[i] = Found{true, o.session, T, rep.best_evidence};
  }
}

}  // namespace v4r::pipeline
