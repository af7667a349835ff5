// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <functional>
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

/// \brief Global illumination that changes smoothly over a cycle (see RenderOptions::cycle_frames):
/// gain(t) = mid + amp * sin(2 pi t / P) spans [gain_min, gain_max] (gain(0) = mid), and the light
/// direction turns about the optical axis by rotation_deg * (1 - cos(2 pi t / P)) / 2.
struct LightChange {
  bool enabled = false;
  double gain_min = 0.5;       ///< darkest global brightness factor (object and background)
  double gain_max = 1.4;       ///< brightest one (bright faces saturate)
  double rotation_deg = 100.0;  ///< largest turn of the light direction about the optical axis, degrees
};

/// \brief A soft-edged shadow band (a robot arm's) sweeping across the image once per cycle, from
/// outside the left/top border (t = 0) to outside the opposite border (t -> P). Darkens object and
/// background alike.
struct ShadowBand {
  bool enabled = false;
  double darkening = 0.5;    ///< fraction of the light removed in the umbra (0..1)
  double width_px = 110.0;   ///< band width between the penumbra mid-lines, pixels
  double penumbra_px = 10.0;  ///< width of the soft edge (0 to full darkening), pixels
  double angle_deg = 25.0;   ///< sweep direction in the image, degrees from +x towards +y
};

/// \brief Static background clutter: strong random straight lines and ellipses, plus lines
/// parallel to the object's silhouette edges 20..40 px outside it (laid out by
/// Renderer::set_scene_reference from the first pose).
struct Clutter {
  bool enabled = false;
  int lines = 30;               ///< random straight lines
  int ellipses = 12;            ///< random ellipses (outlines or filled)
  int near_lines = 6;           ///< lines parallel to silhouette edges (at most)
  double near_min_px = 20.0;    ///< offset of the parallel lines from the silhouette, pixels
  double near_max_px = 40.0;
};

/// \brief An opaque textured occluder (a forearm entering from the bottom of the image, with a
/// rounded end) in front of the object. It sweeps across the object once per cycle: clear of it
/// at t = 0, centred on it at t = P/2 where it covers `peak_coverage` of the object's projected
/// area (calibrated by Renderer::set_scene_reference on the pose of that frame).
struct Occluder {
  bool enabled = false;
  double peak_coverage = 0.38;  ///< fraction of the object's area covered at the peak
  double tilt_deg = 20.0;       ///< arm axis, degrees from the image's vertical
};

/// \brief Blinn-Phong highlights of steel, from a second (overhead) lamp at `light_dir_cam`,
/// added on top of the diffuse shading: strength * (n.h)^shininess * (sheen + (1 - sheen) * glint)
/// * 255, where glint is a fine texture of micro-facets fixed to the object. Within the lobe, the
/// glints saturate small areas; rust is matte.
struct Specular {
  double strength = 0.0;   ///< 0 = off; 1 = the lobe's glints reach +255 grey levels
  double shininess = 40.0;  ///< Blinn exponent
  double sheen = 0.15;     ///< fraction of the highlight that is not glint
  Eigen::Vector3d light_dir_cam{-0.2, -0.9, 0.35};  ///< direction towards the lamp (camera frame)
};

/// \brief Appearance of rendered sequences. Grey levels are 0..255. The defaults are the
/// "regular" condition; see conditions.hpp for the named hard conditions.
struct RenderOptions {
  int supersample = 3;             ///< samples per pixel per axis at edge pixels (anti-aliasing; 1 = off)
  double noise_sigma = 2.0;        ///< sensor noise (approximately Gaussian: scaled sum of 4 uniforms), grey levels
  double salt_pepper = 0.0;        ///< fraction of pixels set to black or white (impulse noise)
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
  std::uint32_t seed = 7;  ///< noise, texture and clutter seed

  /// Frames per cycle P of the time-varying conditions (light, shadow, occluder). 0: the
  /// sequence length in write_sequence, 120 for direct Renderer::render calls.
  int cycle_frames = 0;
  LightChange light_change;
  ShadowBand shadow;
  Clutter clutter;
  Occluder occluder;
  Specular specular;
  /// Motion blur: sub-frame renders averaged per frame when a previous pose is given (1 = off).
  int blur_samples = 1;
  /// Fraction of the frame interval the shutter is open; the exposure ends at the frame's pose.
  double blur_exposure = 1.0;
};

/// \brief Where the occluder of RenderOptions::occluder passes, in pixels. Its centre line is the
/// set of points p with across . p = u(t), u(t) = u_start + (u_end - u_start) * t / P, ending at
/// the tip (axis . p = tip) with a rounded end; it extends beyond the image along -axis. A
/// Renderer starts with a layout over the image centre (set_scene_reference fits it to the object).
struct OccluderLayout {
  Eigen::Vector2d axis{0.0, -1.0};   ///< unit, from the arm's base towards its tip (image up)
  Eigen::Vector2d across{1.0, 0.0};  ///< unit, the sweep direction
  double radius_px = 40.0;           ///< half width of the arm
  double tip = -140.0;               ///< axis coordinate of the tip's centre
  double u_start = 100.0, u_end = 540.0;  ///< across coordinates of the centre line at t = 0 and t = P
};

/// \brief Ground truth of a rendered frame beyond the pose.
struct FrameInfo {
  /// CV_8UC1: 255 where the object is the nearest surface at the pixel centre (at the frame's
  /// pose, ignoring the occluder).
  cv::Mat object_mask;
  cv::Mat occluder_mask;  ///< CV_8UC1: 255 where the occluder covers the pixel centre (all 0 without occluder)
};

/// \brief Software renderer (ray casting against the model's faces and cylinders with
/// supersampling) of a Model seen by a PinholeCamera, including lens distortion. Faces are
/// single-sided (back faces are not drawn: models are closed); cylinders are closed solids
/// (side surface between p1 and p2 plus both end disks). Surfaces are shaded (Lambert + ambient,
/// optional Blinn-Phong highlights) and carry a procedural texture fixed to the object; the
/// background is a static procedural texture (optionally cluttered). Pixels whose 4-neighbours
/// see another surface (silhouettes, face edges, cylinder rims) are supersampled. Optional
/// conditions: light change, shadow, occluder, motion blur, impulse noise (see RenderOptions).
/// Deterministic for a given seed and frame index. render() is const and keeps no state
/// (thread-safe); set_scene_reference() must be called before rendering, not concurrently.
class Renderer {
 public:
  Renderer(const geometry::PinholeCamera& cam, const RenderOptions& opt = {});

  /// Lays out what depends on where the object appears: the clutter lines parallel to its
  /// silhouette (at trajectory.front()) and the occluder's path and width (clear of the object
  /// at frame 0, covering peak_coverage at frame P/2). Without a call, the occluder passes over
  /// the image centre with a default width, and no parallel clutter lines are drawn. write_sequence
  /// calls it. No effect unless clutter or occluder is enabled.
  void set_scene_reference(const model::Model& model, const std::vector<geometry::SE3>& trajectory);

  /// Renders one frame (CV_8UC3 BGR, or CV_8UC1 when !opt.colour) of `model` at pose T_cam_obj;
  /// `frame_index` seeds the sensor noise and sets the phase of the time-varying conditions.
  /// With opt.blur_samples > 1 and `T_prev` (the pose of the previous frame), the frame is the
  /// mean of sub-frame renders along the motion from T_prev to T_cam_obj (exposure ending at
  /// T_cam_obj). `info`, if given, receives the object and occluder masks.
  cv::Mat render(const model::Model& model, const geometry::SE3& T_cam_obj, int frame_index,
                 const geometry::SE3* T_prev = nullptr, FrameInfo* info = nullptr) const;

  [[nodiscard]] const geometry::PinholeCamera& camera() const { return cam_; }
  [[nodiscard]] const RenderOptions& options() const { return opt_; }
  [[nodiscard]] const OccluderLayout& occluder_layout() const { return occluder_; }
  /// The static background (CV_32FC3 BGR, grey levels), including clutter.
  [[nodiscard]] const cv::Mat& background() const { return background_; }

 private:
  geometry::PinholeCamera cam_;
  RenderOptions opt_;
  cv::Mat clean_background_;  ///< CV_32FC3 BGR, grey levels, static, with random clutter only
  cv::Mat background_;        ///< clean_background_ plus clutter laid out around the object
  cv::Mat rays_;           ///< CV_32FC2 (height+2) x (width+2): normalised undistorted coordinates of
                           ///< the pixel centres, with a one-pixel border (entry (y+1, x+1) is pixel (x, y))
  cv::Rect2d ray_bounds_;  ///< bounding box of all entries of rays_ (normalised coordinates)
  std::vector<cv::Point2f> sample_offsets_;  ///< sub-pixel sample offsets (pixels) at edge pixels
  std::vector<float> texture_;               ///< periodic fBm (kTextureSize^2 values in [0, 1]) mapped onto faces
  OccluderLayout occluder_;
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
/// The same texts are in data/box.cao, data/ship_mockup.cao, data/flange.cao, data/ship_section.cao
/// and data/sponge.cao.
std::string box_cao();  ///< 0.20 x 0.15 x 0.10 m box (x, y, z), origin at its centre
/// Welded steel mockup: base plate 0.40 x 0.30 x 0.02 m with a longitudinal and a transverse
/// wall; origin at the centre of the plate's top face, z up.
std::string ship_mockup_cao();
/// Flange: square plate 0.20 x 0.20 x 0.02 m with a cylinder (radius 0.05 m, height 0.06 m,
/// axis z) standing on its centre; origin at the centre of the plate's top face, z up.
std::string flange_cao();
/// Denser ship section for benchmarks: the base plate with two longitudinal walls and three
/// transverse frames between them (27 edges visible in the standard views); origin and axes as
/// the mockup's.
std::string ship_section_cao();
/// The paper's green household sponge as a box, 0.11 x 0.07 x 0.045 m (x, y, z), origin at its
/// centre, every face `colour=0.2,0.6,0.1` (the detector's colour stage); as data/sponge.cao.
std::string sponge_cao();

/// A default 640x480 camera (f = 600 px, principal point at the centre, mild distortion).
geometry::PinholeCamera default_camera();

/// \brief Renders a whole sequence into `dir` (created if needed): frames/000000.png ...,
/// gt.csv (frame,tx,ty,tz,qw,qx,qy,qz), camera.yaml, init_pose.txt (pose of frame 0) and
/// model.cao. Frames NNNNNN.png left in `dir` by a longer earlier sequence are removed. Errors
/// (directory not creatable, invalid model, empty trajectory, write failure) name the offending
/// path; the model and trajectory are validated before anything is written. The conditions in
/// `opt` apply with a cycle of the sequence's length (unless opt.cycle_frames > 0); with motion
/// blur, frame i is exposed from pose i-1 to pose i (frame 0 from a constant-velocity
/// extrapolation backwards). gt.csv holds the pose at the end of each exposure.
Expected<void> write_sequence(const std::string& dir, const std::string& model_cao, const geometry::PinholeCamera& cam,
                              const std::vector<geometry::SE3>& trajectory, const RenderOptions& opt);

/// The same for a model already loaded (a mesh, in metres): `model_file` (e.g. "model.obj") is
/// written into `dir` holding `model_bytes` (the file the model was read from). `progress`, when
/// set, is called after each frame written with (frames written, total).
Expected<void> write_sequence(const std::string& dir, const model::Model& model, const std::string& model_file,
                              const std::string& model_bytes, const geometry::PinholeCamera& cam,
                              const std::vector<geometry::SE3>& trajectory, const RenderOptions& opt,
                              const std::function<void(std::size_t, std::size_t)>& progress = {});

}  // namespace v4r::synth
