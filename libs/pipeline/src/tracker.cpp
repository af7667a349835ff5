// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/tracker.hpp"

#include "v4r/geometry/se3_jacobians.hpp"

namespace v4r::pipeline {

SingleObjectTracker::SingleObjectTracker(std::shared_ptr<const model::Model> model, const geometry::PinholeCamera& cam,
                                         const CycleParams& params)
    : cycle_(params) {
  scene_.add_camera(scene::Camera{"camera", cam, geometry::SE3()});
  (void)scene_.add_object(model ? model->name() : std::string("object"), std::move(model));
}

void SingleObjectTracker::set_pose(const geometry::SE3& T_cam_obj) {
  if (!scene_.objects().empty()) scene_.set_pose(0, T_cam_obj);
}

void SingleObjectTracker::enable_search(std::shared_ptr<const detection::TemplateSet> templates,
                                        const ObjectSearchParams& sp, const detection::DetectorParams& dp) {
  if (scene_.objects().empty()) return;
  search_ = std::make_unique<ObjectSearch>(cycle_.params(), sp, dp);
  search_->add_object(scene_, 0, std::move(templates));
}

void SingleObjectTracker::set_tag_start(std::unique_ptr<detection::TagStart> tag) {
  if (search_) search_->set_tag_start(0, std::move(tag));
}

void SingleObjectTracker::start_search() {
  if (!scene_.objects().empty()) scene_.start_search(0);
}

FrameResult SingleObjectTracker::track(const image::ImageView& grey, const image::ColourView& colour, double stamp_s) {
  const CameraImage img{grey, colour};
  const CycleReport& rep = cycle_.process(scene_, std::span<const CameraImage>(&img, 1), stamp_s);
  FrameResult r;
  if (!scene_.objects().empty()) {
    const scene::Object& o = scene_.objects()[0];
    r.T_cam_obj = o.T_ref_obj;
    r.T_cam_obj_filtered = o.T_ref_obj_filtered;
    r.velocity = o.velocity;
    r.covariance = geometry::translation_rotation_covariance(o.T_ref_obj, o.covariance);
    r.report = rep.objects[0];
  }
  if (search_ && !scene_.objects().empty()) {
    r.search = search_->update(scene_, std::span<const CameraImage>(&img, 1), rep.stamp_s)[0];  // (the cycle's stamp)
    const scene::Object& o = scene_.objects()[0];
    if (r.search.locked) {  // found and confirmed on this frame: the pose of the search
      r.T_cam_obj = r.T_cam_obj_filtered = o.T_ref_obj;
      r.velocity.setZero();
      r.covariance = geometry::translation_rotation_covariance(o.T_ref_obj, o.covariance);
      r.report.evidence = o.evidence;
      r.report.quality = o.quality;
    }
    r.report.status = o.status;
  }
  r.cycle_ms = rep.cycle_ms + r.search.search_ms;  // the frame's whole tracking time
  r.visibility_ms = rep.visibility_ms;
  r.track_ms = rep.track_ms;
  r.solve_ms = rep.solve_ms;
  r.degrade_level = rep.degrade_level;
  r.overruns = rep.overruns;
  return r;
}

}  // namespace v4r::pipeline
