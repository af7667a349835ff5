// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "v4r/core/expected.hpp"
#include "v4r/estimation/pose_solver.hpp"
#include "v4r/features/ellipse_tracker.hpp"
#include "v4r/features/line_tracker.hpp"
#include "v4r/filter/pose_filter.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/model/model.hpp"

namespace v4r::scene {

/// \brief A camera of the scene: intrinsics and its pose in the reference frame.
struct Camera {
  std::string name;
  geometry::PinholeCamera intrinsics;
  geometry::SE3 T_ref_cam;  ///< maps camera coordinates into the reference frame
};

/// State of one image feature in one view.
enum class FeatureStatus : std::uint8_t {
  kNotFound,  ///< never found yet: searched at its projection with the wide search window
  kFound,     ///< found in the last frame: tracked in its window
  kLost,      ///< found before, missing now: re-projected from the model and searched again
  kOutlier,   ///< found but rejected by the pose solver's outlier detection this frame
};

/// \brief An image line linked to a model edge (paper 2.1: image features are linked to model
/// features), with its tracking state.
struct LineFeature {
  model::Index edge = model::kNone;  ///< index into Model::lines()
  FeatureStatus status = FeatureStatus::kNotFound;
  bool visible = false;               ///< visible in the current prediction
  bool ambiguous = false;             ///< visible, but side by side with another edge too close to split: not tracked
  features::SearchRange range;        ///< where its window may find it (split from a side-by-side edge)
  bool grazing = false;               ///< hidden, but bounds a face seen at a grazing angle (may show as a sliver)
  /// Tracked for itself and a side-by-side edge too close to tell apart (a thin plate's two
  /// edges, a face seen edge-on): X1, X2 are then the pair's mid-line and sigma_px is widened.
  bool merged = false;
  double sigma_px = 0.0;              ///< a-priori noise of its line observation (0: the cycle's default)
  Eigen::Vector3d X1 = Eigen::Vector3d::Zero(), X2 = Eigen::Vector3d::Zero();  ///< visible part, object frame
  features::Segment2 predicted;       ///< projection of the visible part (pixels)
  features::LineTrackState track;     ///< state the tracker carries between frames
  features::LineMeasurement measurement;  ///< last measurement (pixels)
  Eigen::Vector2d line_n1 = Eigen::Vector2d::Zero(), line_n2 = Eigen::Vector2d::Zero();  ///< measured line, normalised undistorted coordinates
  bool dropped = false;               ///< left out by the time budget this cycle
  bool retrack = false;               ///< transient: measure again in the next pass of this cycle
  int frames_missing = 0;             ///< consecutive frames not found
};

/// \brief An image ellipse (or elliptic arc) linked to a model circle arc (paper 3.2): the
/// projected tracking lines and the last measurement.
struct ArcFeature {
  static constexpr int kMaxSamples = 64;
  model::Index arc = model::kNone;    ///< index into Model::arcs()
  FeatureStatus status = FeatureStatus::kNotFound;
  bool visible = false;
  bool dropped = false;               ///< left out by the time budget this cycle
  bool retrack = false;
  int samples = 0;                    ///< visible tracking lines this cycle
  std::array<Eigen::Vector3d, kMaxSamples> X;  ///< model points of the tracking lines, object frame
  int edges = 0;                      ///< edge points of the last measurement (ellipse inliers)
  std::array<Eigen::Vector2d, kMaxSamples> edge_px;  ///< their positions, pixels
  features::EllipseTrackState track;
  features::EllipseMeasurement measurement;
  int frames_missing = 0;
};

/// \brief An object as seen by one camera: the image features and the view pose.
struct View {
  std::size_t camera = 0;         ///< index into Scene::cameras()
  geometry::SE3 T_cam_obj;        ///< view pose: T_cam_ref * T_ref_obj at the prediction, then at the measurement
  std::vector<LineFeature> lines;  ///< one per model edge
  std::vector<ArcFeature> arcs;    ///< one per model circle arc
  std::vector<std::uint8_t> face_visible;  ///< per model face, with hysteresis
  /// Edge evidence at the view's pose after the last cycle: samples along the projected model
  /// edges and how many of them the image confirms (features::EdgeEvidence).
  int evidence_samples = 0, evidence_matched = 0;
  /// Silhouette contrast at the same pose: colour samples just outside the silhouette edges, and
  /// how many of them look like the object's inside (features::SilhouetteContrast).
  int leak_samples = 0, leak_matched = 0;
};

/// Tracking state of an object. kSearching: not found yet, or lost for long and searched again
/// over the image (pipeline::ObjectSearch); the cycle does not track it and it has no pose.
enum class TrackStatus : std::uint8_t { kUninitialised, kTracking, kDegraded, kLost, kSearching };
const char* to_string(TrackStatus s);
/// The vision cycle measures the object: its pose was set or found (not uninitialised, not
/// being searched for).
inline bool is_tracked(TrackStatus s) { return s != TrackStatus::kUninitialised && s != TrackStatus::kSearching; }

/// \brief A tracked object (paper 2.1): a model, one view per camera, and its pose in the
/// reference frame.
struct Object {
  std::string name;
  std::shared_ptr<const model::Model> model;
  std::vector<View> views;
  geometry::SE3 T_ref_obj;  ///< reported pose (the filter's estimate; while lost, the prediction)
  /// Covariance of T_ref_obj (left tangent, reference frame): of the estimate while tracked, of
  /// the prediction (growing with time) while lost.
  geometry::Matrix6d covariance = geometry::Matrix6d::Zero();
  TrackStatus status = TrackStatus::kUninitialised;
  double quality = 0.0;  ///< 0..1: edge evidence, lowered by large residuals
  double evidence = 0.0;  ///< share of the projected model's edge samples the image confirms (all views)
  /// Share of the colour samples just outside the silhouette that look like the object's inside
  /// (all views; -1: no silhouette sampled), and its running mean over frames reported
  /// `tracking` (-1: none yet): what this object against its surroundings leaks at a right pose.
  double leak = -1.0;
  int leak_samples = 0;
  double leak_typical = -1.0;
  int leak_wait = 0;  ///< frames until the silhouette leak is sampled again (0: this frame)
  filter::PoseFilter filter;          ///< predicts T_ref_obj for tracking (constant velocity)
  filter::PoseFilter smoother;        ///< the same measurements with adaptive process noise: the reported pose
  geometry::SE3 T_ref_obj_filtered;   ///< filter output after the last cycle
  geometry::SE3 T_pred;               ///< prediction for the current cycle
  geometry::Matrix6d covariance_pred = geometry::Matrix6d::Zero();  ///< of T_pred (left tangent, reference frame); zero: none
  geometry::Vector6d velocity = geometry::Vector6d::Zero();  ///< (v, w) m/s, rad/s, left tangent of T_ref_obj
  double last_stamp = -1.0;           ///< seconds: time of the last cycle of this object
  /// The cycle's verdict on its last measurement from the features alone (used, weak, not used):
  /// drives the search width, the prediction and the prior; `status` is what is reported.
  TrackStatus measured = TrackStatus::kUninitialised;
  int bad_frames = 0;                 ///< consecutive frames whose measurement was weak or not used
  /// Running mean of the measured poses' normalised jitter (chi^2 of the third difference of
  /// four consecutive measurements, over 6 degrees of freedom): 1 when the measurements scatter
  /// as their covariance says, more when they jitter more (a blurred image, a weak geometry);
  /// the reported covariance is scaled by it where it exceeds 1 (CycleParams::consistency_rate).
  double consistency = 1.0;
  geometry::SE3 T_meas_prev[3];           ///< the last three measured poses used for it, newest first
  geometry::Matrix6d cov_meas_prev[3] = {geometry::Matrix6d::Zero(), geometry::Matrix6d::Zero(),
                                         geometry::Matrix6d::Zero()};  ///< and their reported covariances
  int consistency_frames = 0;             ///< consecutive measurements held in T_meas_prev (0..3)
  /// This frame's image and features by themselves say `lost` (the measurement was not used or
  /// the evidence is below status.lost_evidence); `status` stays lost longer (hysteresis).
  bool lost_by_image = false;
  /// The pose has been measured from the image alone (a `tracking` frame) since it was last set:
  /// only then is the prediction good enough to serve as a prior, and to start the per-sample
  /// fit from (a start pose may be far off). The search sets it for a pose measured on the
  /// image it refines it on (a detector hypothesis: pipeline::ObjectSearch).
  bool confirmed = false;
  /// The pose of the last frame reported `tracking` (the image supported it), kept while the
  /// object is lost or searched: a recovery starts there, not at the prediction held since.
  geometry::SE3 T_ref_obj_tracked;
  bool tracked_once = false;  ///< T_ref_obj_tracked is set
  /// The filter's velocity at that frame (left tangent, reference frame) and the frame's time:
  /// a search after a loss also looks where the object has moved on to since.
  geometry::Vector6d velocity_tracked = geometry::Vector6d::Zero();
  double stamp_tracked = -1.0;
};

/// \brief The scene: cameras and objects, owned by value. Adding an object creates one view per
/// existing camera; adding a camera adds a view to every object.
class Scene {
 public:
  std::size_t add_camera(Camera cam);
  /// Adds an object with a model; its pose is unset (kUninitialised) until set_pose.
  Expected<std::size_t> add_object(std::string name, std::shared_ptr<const model::Model> model);
  /// Gives an object a new model and keeps its tracking state (pose, filter, status): its views
  /// are rebuilt for the new model's features (found again from the next frame); its place in
  /// the scene stays. false if there is none at `object` or the model is null.
  bool replace_model(std::size_t object, std::shared_ptr<const model::Model> model);
  /// Removes an object (later objects move down by one); false if there is none at `object`.
  bool remove_object(std::size_t object);
  /// Sets the pose of an object in the reference frame and (re)starts its tracking: its filters,
  /// status and every view start anew (as made for this pose: no edge keeps a measurement, a
  /// learned polarity or appearance, no face its visibility from an earlier pose). Allocates nothing.
  void set_pose(std::size_t object, const geometry::SE3& T_ref_obj);
  /// Marks an object as searched for (kSearching): it keeps no pose and the vision cycle leaves
  /// it to the search until a pose is set (set_pose).
  void start_search(std::size_t object);

  /// The cameras, in the order added (View::camera indexes them).
  [[nodiscard]] std::span<const Camera> cameras() const { return cameras_; }
  /// The objects, in the order added: their state may be edited, the set only through
  /// add_object (views must match the cameras).
  [[nodiscard]] std::span<Object> objects() { return objects_; }
  [[nodiscard]] std::span<const Object> objects() const { return objects_; }
  /// Index of the object with this name, or -1.
  [[nodiscard]] long find_object(const std::string& name) const;

 private:
  static View make_view(std::size_t camera, const model::Model& model);
  std::vector<Camera> cameras_;
  std::vector<Object> objects_;
};

}  // namespace v4r::scene
