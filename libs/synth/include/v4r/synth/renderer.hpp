// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "v4r/core/expected.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/look_at.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"

namespace v4r::synth {

/// \brief Appearance of rendered sequences. Grey levels are 0..255.
struct RenderOptions {
  int supersample = 3;             ///< samples per pixel per axis at edge pixels (anti-aliasing; 1 = off)
  double noise_sigma = 2.0;        ///< sensor noise (approximately Gaussian: scaled sum of 4 uniforms), grey levels
  double texture_strength = 0.25;  ///< amplitude of the rust-like texture on faces (0..1)
  double texture_scale = 0.03;     ///< metres: size of the largest rust blotches (object frame)
  /// Direction *towards* the light, camera frame (need not be unit): from the upper left,
  /// behind the camera. With the defaults, the faces of a box seen from above (30-60 degrees)
  /// differ by >= ~30 grey levels from each other and from the background from most azimuths.
  Eigen::Vector3d light_dir_cam{-0.40, -0.50, -0.77};
  double ambient = 0.45;            ///< ambient light fraction
  bool textured_background = true;  ///< procedural background (else uniform background_grey)
  /// Mean background level, grey levels: darker than any lit face (faces span ~100..210).
  double background_grey = 65.0;
  bool colour = true;      ///< render BGR (else grey)
  std::uint32_t seed = 7;  ///< noise and texture seed
};

/// \brief Software renderer (ray casting against the model's faces with supersampling) of a
/// Model seen by a PinholeCamera, including lens distortion. Faces are single-sided (back
/// faces are not drawn: models are closed), shaded (Lambert + ambient) and carry a procedural
/// texture fixed to the object; the background is a static procedural texture. Deterministic
/// for a given seed and frame index. Thread-safe: render() is const and keeps no state.
class Renderer {
 public:
  Renderer(const geometry::PinholeCamera& cam, const RenderOptions& opt = {});
  /// Renders one frame (CV_8UC3 BGR, or CV_8UC1 when !opt.colour) of `model` at pose T_cam_obj;
  /// `frame_index` seeds the sensor noise.
  cv::Mat render(const model::Model& model, const geometry::SE3& T_cam_obj, int frame_index) const;

  [[nodiscard]] const geometry::PinholeCamera& camera() const { return cam_; }
  [[nodiscard]] const RenderOptions& options() const { return opt_; }

 private:
  geometry::PinholeCamera cam_;
  RenderOptions opt_;
  cv::Mat background_;     ///< CV_32FC3 BGR, grey levels, static
  cv::Mat rays_;           ///< CV_32FC2 (height+2) x (width+2): normalised undistorted coordinates of
                           ///< the pixel centres, with a one-pixel border (entry (y+1, x+1) is pixel (x, y))
  cv::Rect2d ray_bounds_;  ///< bounding box of all entries of rays_ (normalised coordinates)
  std::vector<cv::Point2f> sample_offsets_;  ///< sub-pixel sample offsets (pixels) at edge pixels
  std::vector<float> texture_;               ///< periodic fBm (kTextureSize^2 values in [0, 1]) mapped onto faces
};

/// \brief A smooth pose trajectory: the object starts at `T0` and moves with sinusoidal
/// translations (camera axes) and rotations (about camera-parallel axes through the object
/// origin) of the given amplitudes over `frames` frames. Each axis has its own frequency, so
/// the motion does not repeat within a few hundred frames; frame 0 is exactly T0.
struct TrajectorySpec {
  int frames = 120;
  geometry::SE3 T0;               ///< pose of frame 0 (T_cam_obj)
  double translation_amp = 0.05;  ///< metres, along the camera x and y axes
  double rotation_amp = 0.25;     ///< radians, about each axis
  double depth_amp = 0.1;         ///< metres along the optical axis
  double speed = 1.0;             ///< multiplies the inter-frame motion (phase rate)
};
std::vector<geometry::SE3> make_trajectory(const TrajectorySpec& spec);

/// Built-in test objects, as `.cao` text (so they go through the same reader as user models).
/// The same texts are in data/box.cao and data/ship_mockup.cao.
std::string box_cao();  ///< 0.20 x 0.15 x 0.10 m box (x, y, z), origin at its centre
/// Welded steel mockup: base plate 0.40 x 0.30 x 0.02 m with a longitudinal and a transverse
/// wall; origin at the centre of the plate's top face, z up.
std::string ship_mockup_cao();

/// A default 640x480 camera (f = 600 px, principal point at the centre, mild distortion).
geometry::PinholeCamera default_camera();

/// \brief Renders a whole sequence into `dir` (created if needed): frames/000000.png ...,
/// gt.csv (frame,tx,ty,tz,qw,qx,qy,qz), camera.yaml, init_pose.txt (pose of frame 0) and
/// model.cao. Frames NNNNNN.png left in `dir` by a longer earlier sequence are removed. Errors
/// (directory not creatable, invalid model, empty trajectory, write failure) name the offending
/// path; the model and trajectory are validated before anything is written.
Expected<void> write_sequence(const std::string& dir, const std::string& model_cao, const geometry::PinholeCamera& cam,
                              const std::vector<geometry::SE3>& trajectory, const RenderOptions& opt);

}  // namespace v4r::synth
