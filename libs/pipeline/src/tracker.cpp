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
  r.cycle_ms = rep.cycle_ms;
  r.visibility_ms = rep.visibility_ms;
  r.track_ms = rep.track_ms;
  r.solve_ms = rep.solve_ms;
  r.degrade_level = rep.degrade_level;
  r.overruns = rep.overruns;
  return r;
}

}  // namespace v4r::pipeline
