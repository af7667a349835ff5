// v4r - robust model-based object tracking. MIT licence.
#include "v4r/scene/scene.hpp"

#include <algorithm>

#include <fmt/format.h>

namespace v4r::scene {

const char* to_string(TrackStatus s) {
  switch (s) {
    case TrackStatus::kUninitialised: return "uninitialised";
    case TrackStatus::kTracking: return "tracking";
    case TrackStatus::kDegraded: return "degraded";
    case TrackStatus::kLost: return "lost";
    case TrackStatus::kSearching: return "searching";
  }
  return "unknown";
}

namespace {

/// A view's features and faces as at its start: each line and arc of the model in its own index,
/// nothing found, measured or learned, no face visible yet (the view's sizes are kept: no
/// allocation).
void start_anew(View& v) {
  for (std::size_t i = 0; i < v.lines.size(); ++i) {
    v.lines[i] = LineFeature{};
    v.lines[i].edge = static_cast<model::Index>(i);
  }
  for (std::size_t i = 0; i < v.arcs.size(); ++i) {
    v.arcs[i] = ArcFeature{};
    v.arcs[i].arc = static_cast<model::Index>(i);
  }
  std::fill(v.face_visible.begin(), v.face_visible.end(), std::uint8_t{0});
  v.evidence_samples = v.evidence_matched = v.leak_samples = v.leak_matched = 0;
}

}  // namespace

View Scene::make_view(std::size_t camera, const model::Model& model) {
  View v;
  v.camera = camera;
  v.lines.resize(model.lines().size());
  v.arcs.resize(model.arcs().size());
  v.face_visible.resize(model.faces().size());
  start_anew(v);
  return v;
}

std::size_t Scene::add_camera(Camera cam) {
  cameras_.push_back(std::move(cam));
  const std::size_t ci = cameras_.size() - 1;
  for (Object& o : objects_) o.views.push_back(make_view(ci, *o.model));
  return ci;
}

Expected<std::size_t> Scene::add_object(std::string name, std::shared_ptr<const model::Model> model) {
  if (!model) return make_error(fmt::format("object '{}' has no model", name));
  if (find_object(name) >= 0) return make_error(fmt::format("an object named '{}' exists already", name));
  Object o;
  o.name = std::move(name);
  o.model = std::move(model);
  for (std::size_t ci = 0; ci < cameras_.size(); ++ci) o.views.push_back(make_view(ci, *o.model));
  objects_.push_back(std::move(o));
  return objects_.size() - 1;
}

void Scene::set_pose(std::size_t object, const geometry::SE3& T_ref_obj) {
  Object& o = objects_.at(object);
  o.T_ref_obj = T_ref_obj;
  o.T_ref_obj_filtered = T_ref_obj;
  o.velocity.setZero();
  o.status = TrackStatus::kTracking;
  o.measured = TrackStatus::kTracking;
  o.lost_by_image = false;
  o.bad_frames = 0;
  o.consistency = 1.0;
  o.consistency_frames = 0;
  o.confirmed = false;
  o.tracked_once = false;
  o.last_stamp = -1.0;
  o.leak_wait = 0;
  geometry::Matrix6d cov = geometry::Matrix6d::Zero();
  cov.diagonal() << 1e-4, 1e-4, 1e-4, 1e-3, 1e-3, 1e-3;  // 1 cm, 1.8 degrees: a hint, not a measurement
  o.filter.reset(T_ref_obj, cov);
  o.smoother.reset(T_ref_obj, cov);
  o.covariance = cov;
  // Every view starts anew, as if made for this pose (make_view): nothing of a previous pose
  // (face visibility with its hysteresis, pairs, ranges, measurements) carries over to it.
  for (View& v : o.views) {
    start_anew(v);
    v.T_cam_obj = cameras_[v.camera].T_ref_cam.inverse() * T_ref_obj;
  }
}

bool Scene::replace_model(std::size_t object, std::shared_ptr<const model::Model> model) {
  if (object >= objects_.size() || !model) return false;
  Object& o = objects_[object];
  o.model = std::move(model);
  for (View& v : o.views) {
    View fresh = make_view(v.camera, *o.model);
    fresh.T_cam_obj = cameras_[v.camera].T_ref_cam.inverse() * o.T_ref_obj;
    v = std::move(fresh);
  }
  return true;
}

bool Scene::remove_object(std::size_t object) {
  if (object >= objects_.size()) return false;
  objects_.erase(objects_.begin() + static_cast<std::ptrdiff_t>(object));
  return true;
}

void Scene::start_search(std::size_t object) {
  Object& o = objects_.at(object);
  o.status = TrackStatus::kSearching;
  o.measured = TrackStatus::kLost;
  o.lost_by_image = false;
  o.quality = 0.0;
  o.evidence = 0.0;
  o.confirmed = false;
  o.velocity.setZero();
}

long Scene::find_object(const std::string& name) const {
  for (std::size_t i = 0; i < objects_.size(); ++i)
    if (objects_[i].name == name) return static_cast<long>(i);
  return -1;
}

}  // namespace v4r::scene
