// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "v4r/core/clock.hpp"
#include "v4r/core/thread_team.hpp"
#include "v4r/features/edge_evidence.hpp"
#include "v4r/features/silhouette_contrast.hpp"
#include "v4r/pipeline/arc_measurement.hpp"
#include "v4r/pipeline/camera_image.hpp"
#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/pipeline/cycle_report.hpp"
#include "v4r/pipeline/junction_measurement.hpp"
#include "v4r/pipeline/line_measurement.hpp"
#include "v4r/pipeline/measure_context.hpp"
#include "v4r/pipeline/object_solver.hpp"
#include "v4r/pipeline/observation_buffer.hpp"
#include "v4r/pipeline/sample_refinement.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief Step 3 of the vision cycle for one object (paper 3): track its features in every view,
/// assemble the observations of all views (lines, junctions, ellipse points), solve T_ref_obj
/// (refine passes re-measure what the solve rejected), settle the feature states, test the image
/// evidence and update the object's filters and status.
///
/// It holds the scratch of the measurement units and the solver, so the vision cycle keeps one
/// per thread: objects (or the views of one object, through set_view_team) are then measured in
/// parallel. An object's result does not depend on which unit measured it. Counters of the frame
/// (windows, samples, times, edge pixels for overlays) are kept per unit and summed by the cycle.
/// After reserve(), measure() allocates nothing and throws only what a unit throws.
class ObjectMeasurer {
 public:
  ObjectMeasurer(const CycleParams& params, Clock::time_point (*now)());

  /// Buffers for every object of the scene and its views (allocates when they grow).
  void reserve(const scene::Scene& scene);
  /// Starts a frame: the cycle's context (frame, budget levels), counters and edge pixels reset.
  void begin_frame(const MeasureContext& cycle);
  /// Lets measure() track an object's views in parallel on `team`, view k on member k % size
  /// with peers[member]'s scratch (peers[0] is this unit). nullptr: one after the other.
  void set_view_team(ThreadTeam* team, std::span<ObjectMeasurer* const> peers);

  /// Measures `obj` (tracked, predicted by the cycle) on `images` and updates it; `rep` gets the
  /// object's counts and status.
  void measure(const scene::Scene& scene, scene::Object& obj, std::span<const CameraImage> images, ObjectReport& rep,
               double stamp_s);

  /// This frame's counters.
  [[nodiscard]] const MeasureContext& context() const { return ctx_; }
  [[nodiscard]] double track_ms() const { return track_ms_; }
  [[nodiscard]] double solve_ms() const { return solve_ms_; }
  /// Edge pixels this unit measured in the frame, per camera.
  [[nodiscard]] const std::vector<Eigen::Vector2d>& edgels(std::size_t camera) const {
    static const std::vector<Eigen::Vector2d> kEmpty;
    return camera < edgels_.size() ? edgels_[camera] : kEmpty;
  }

 private:
  struct TrackStep {
    int found = 0;    // features found
    int refound = 0;  // of which missed by the first pass
  };
  /// Tracks the lines and arcs of one view with this unit's scratch and counters.
  TrackStep track_view(const scene::Scene& scene, const scene::Object& obj, scene::View& view,
                       std::span<const CameraImage> images);
  /// Tracks views [first, last), in parallel over the view team when there is one.
  TrackStep track_views(const scene::Scene& scene, scene::Object& obj, std::span<const CameraImage> images,
                        std::size_t first, std::size_t last);
  /// The track + solve passes over views [first, last) of the object: one solve of T_ref_obj.
  ObjectSolve measure_views(const scene::Scene& scene, scene::Object& obj, std::span<const CameraImage> images,
                            std::size_t first, std::size_t last, ObjectReport& rep);

  /// The per-sample measurement over the object's views with an image, from `T_ref_predicted`:
  /// kept (in solves_[0] and the views) when its edge evidence over the views beats the line
  /// solve's by samples.margin. Its evidence takes the silhouette's colours with `contrast` (null
  /// on a frame they are not sampled, as for the line solve's pose).
  ObjectReport::SampleFit choose_sample_pose(const scene::Scene& scene, scene::Object& obj,
                                             const geometry::SE3& T_ref_predicted, std::span<const CameraImage> images,
                                             features::SilhouetteContrast* contrast);

  CycleParams p_;
  Clock::time_point (*now_)();
  LineMeasurement lines_;
  ArcMeasurement arcs_;
  JunctionMeasurement junctions_;
  ObjectSolver solver_;
  features::EdgeEvidence evidence_;
  features::SilhouetteContrast contrast_;
  SampleRefiner samples_;
  MeasureContext ctx_;
  ObservationBuffer buffer_;
  std::vector<ObjectSolve> solves_;  // per solve of the object being measured
  std::vector<std::vector<Eigen::Vector2d>> edgels_;  // per camera
  double track_ms_ = 0.0, solve_ms_ = 0.0;
  ThreadTeam* view_team_ = nullptr;
  std::span<ObjectMeasurer* const> peers_;
};

}  // namespace v4r::pipeline
