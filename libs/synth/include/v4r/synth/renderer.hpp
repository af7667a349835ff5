// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"

namespace v4r::synth {

/// \brief Appearance of rendered sequences.
struct RenderOptions {
  int supersample = 3;          ///< samples per pixel per axis (anti-aliasing)
  double noise_sigma = 2.0;     ///< Gaussian sensor noise, grey levels
  double texture_strength = 0.25;  ///< amplitude of the rust-like texture on faces (0..1)
  Eigen::Vector3d light_dir_cam{0.3, -0.5, -1.0};  ///< direction *towards* the light, camera frame
  double ambient = 0.35;        ///< ambient light fraction
  bool textured_background = true;  ///< procedural background (else uniform grey)
  bool colour = true;           ///< render BGR (else grey)
  std::uint32_t seed = 7;       ///< noise and texture seed
};

/// \brief Software renderer (ray casting against the model's faces with supersampling) of a
/// Model seen by a PinholeCamera, including lens distortion. Faces are shaded (Lambert) and
/// carry a procedural texture fixed to the object; the background is a static procedural
/// texture. Deterministic for a given seed and frame index.
class Renderer {
 public:
  Renderer(const geometry::PinholeCamera& cam, const RenderOptions& opt = {});
  /// Renders one frame (CV_8UC3 BGR, or CV_8UC1 when !opt.colour).
  cv::Mat render(const model::Model& model, const geometry::SE3& T_cam_obj, int frame_index) const;

 private:
  geometry::PinholeCamera cam_;
  RenderOptions opt_;
  cv::Mat background_;
};

/// \brief A smooth pose trajectory: the object starts at `T0` and moves with sinusoidal
/// translations and rotations of the given amplitudes over `frames` frames.
struct TrajectorySpec {
  int frames = 120;
  geometry::SE3 T0;             ///< pose of frame 0 (T_cam_obj)
  double translation_amp = 0.05;  ///< metres
  double rotation_amp = 0.25;     ///< radians
  double depth_amp = 0.1;         ///< metres along the optical axis
  double speed = 1.0;             ///< multiplies the inter-frame motion
};
std::vector<geometry::SE3> make_trajectory(const TrajectorySpec& spec);

/// Built-in test objects, as `.cao` text (so they go through the same reader as user models).
std::string box_cao();           ///< 0.20 x 0.15 x 0.10 m box, origin at its centre
std::string ship_mockup_cao();   ///< welded steel mockup: base plate with perpendicular walls

/// A default 640x480 camera (f = 600 px, principal point at the centre, mild distortion).
geometry::PinholeCamera default_camera();

/// \brief Renders a whole sequence into `dir`: frames/000000.png ..., gt.csv (frame,tx,ty,tz,
/// qw,qx,qy,qz), camera.yaml, init_pose.txt (pose of frame 0) and model.cao.
Expected<void> write_sequence(const std::string& dir, const std::string& model_cao, const geometry::PinholeCamera& cam,
                              const std::vector<geometry::SE3>& trajectory, const RenderOptions& opt);

}  // namespace v4r::synth
