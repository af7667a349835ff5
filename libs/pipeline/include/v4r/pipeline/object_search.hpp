// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <stop_token>
#include <vector>

#include "v4r/core/params.hpp"
#include "v4r/detection/detector.hpp"
#include "v4r/detection/tag_start.hpp"
#include "v4r/pipeline/vision_cycle.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief When and how an object without a pose is searched for (issue 10: automatic start and
/// recovery after loss). Registered as `search.*` (add_search_params).
struct ObjectSearchParams {
  bool enabled = true;           ///< objects lost for lost_frames are searched again
  int lost_frames = 3;           ///< frames reported `lost` in a row after which an object is searched
  /// Search frames on which perturbed restarts around the last pose are tried (10 s at 30 fps): a
  /// lost object is most often still near where it was lost, under blur or behind something, and
  /// the restarts cost a fraction of the whole-image detector. (10 frames lost the blurred thin
  /// plates of the benchmark for 50-100 frames, which the detector did not find.)
  int local_frames = 300;
  int restarts = 4;              ///< perturbed restarts per search frame (around the last pose, and the extrapolated one)
  double restart_shift = 0.5;    ///< restart offsets across the view: this times the model's bounding radius
  /// The restarts are tried around the last tracked pose and, if the object was moving, around
  /// where its velocity then takes it by now (the filter's prediction from the last tracked
  /// frame; a partly hidden object moves on while it is lost), extrapolated for at most this
  /// long (0: the last pose only).
  double extrapolate_s = 1.0;
  int hypotheses = 10;           ///< best detector hypotheses refined by the tracker per search frame
  /// Each of those hypotheses is also refined by the tracker from its template's pose (the
  /// detector's pose before its own edge alignment). That alignment can be pulled onto an edge of
  /// the object's texture (a printed stripe parallel to a real edge) and away from a template
  /// that lay in the true pose's basin; the tracker, with its own cues, may still reach it.
  bool template_starts = true;
  int refine_cycles = 3;         ///< vision cycles run on a hypothesis (first wide windows, then normal)
  /// A refined hypothesis is accepted when the cycle reports `tracking` on it and this share of
  /// the projected model's edge samples is confirmed by the image (features::EdgeEvidence).
  double accept_evidence = 0.7;
  /// A perturbed restart around the last tracked pose is accepted at this share, between a
  /// tracked pose's (status.tracking_evidence) and a detection's (accept_evidence): the last pose
  /// is a prior the whole-image detector lacks, and the object may still be partly occluded.
  /// One accepted: the detector is not run on that frame (around the last pose first, then the
  /// whole image).
  double local_accept_evidence = 0.6;
  /// A refined hypothesis below its accept share but at or above this one is accepted when the
  /// detector's edge test verifies its pose (detect.verify.accept_score; gradients summed along
  /// the edge, threshold relative to the frame's noise): under heavy sensor noise the tracker's
  /// windows raise their thresholds, and the image confirms fewer samples of a pose in plain
  /// view. >= accept_evidence: off.
  double edge_test_evidence = 0.4;
  /// A detector hypothesis verified by its colour (its edges score below
  /// detect.verify.accept_score, but its outline parts its colours from the surroundings: the
  /// colour test, detect.verify.leak_score, or the stand-out verdict, detect.verify.stand_out_*;
  /// typically an object partly hidden, whose hidden edges no image confirms) is accepted when
  /// the tracker's refinement keeps it within confirm_translation / confirm_rotation and this
  /// share of its projected model's edge samples is confirmed; so is the candidate it gives on the
  /// next frame. >= accept_evidence: off, and the detector's colour verdicts are not run.
  double stand_out_evidence = 0.4;
  /// With no detector hypothesis verified on the frame, the best-scoring one, when its edge score
  /// is at least top_score, is accepted at this share, when the tracker's refinement keeps it
  /// within confirm_translation / confirm_rotation (a partly hidden object whose outline does not
  /// part its colours from the surroundings: a grey plate structure before a dark background).
  /// Its candidate is confirmed on the next frame at accept_evidence less confirm_margin, as any
  /// other. >= accept_evidence: off.
  double top_evidence = 0.6;
  /// (see top_evidence) The section 30 % occluded: the right pose's edge score is often just under
  /// 0.5 (0.49-0.50 in 3 of the 120 evaluation renders' misses); 0.45 found 91 -> 94 of those
  /// renders and 86 -> 87 of another 120, wrong as before; one more false accept of 1500.
  double top_score = 0.45;
  /// A found pose must lie in the detector's view range (detect.views.*: elevation, in-plane
  /// turn, distance) widened by this many degrees (distance: by the ratio 1 + margin / 45),
  /// modulo the model's symmetries: an edge image can fit a turned and farther box as well as
  /// the true one (a Necker-like ambiguity), and the range says which views can occur.
  double view_margin_deg = 15.0;
  /// An accepted pose becomes `tracking` when the next frame, tracked from it, accepts it again
  /// within these limits (consistency over 2 frames).
  double confirm_translation_m = 0.03;
  double confirm_rotation_deg = 10.0;
  /// The next frame confirms a found pose at the evidence share it was accepted at less this
  /// margin (a hysteresis: the same pose tracked again from where it was found; on the same still
  /// image, poses accepted at 0.7 or more were tracked again at 0.63-0.69).
  double confirm_margin = 0.1;
  /// The next frame's tracking may report a found pose `degraded` (fewer than half its features
  /// used: a blurred thin plate, whose close edge pairs the windows drop) and still confirm it,
  /// when it keeps the pose within this share of confirm_translation and confirm_rotation and the
  /// image confirms at least the share the pose was accepted at, without the margin (0: off).
  double confirm_degraded = 0.3;
  /// Two frames' searches that agree confirm a pose: when the next frame tracks the found pose
  /// beyond the confirm limits but within this factor of them, to a pose the image supports no
  /// better than the found one (the tracker sliding along a direction blur leaves weak, not to a
  /// better fit), and that frame's own search finds the same pose again within the limits, the
  /// pose is confirmed (<= 1: off).
  double refound_factor = 2.0;
  /// The found poses of a search frame are ranked by the edge samples the image confirms times
  /// their share of the projected model's samples to this power (and the pose solve's residual,
  /// see choose_found_pose): a pose fitted to clutter, larger than the object, may confirm more
  /// samples than the object at a far lower share (a box on clutter: 0.76 against 0.99). 2 let it
  /// win; 4 does not, and ranks a partly hidden object (its share lower) as before; 6 cost those.
  double rank_evidence_power = 4.0;
  /// With no pose accepted on a search frame, a pose the tracker holds (`tracking`, in the view
  /// range, not leaking) at consensus_evidence of its samples or more is accepted when starts from
  /// at least consensus_candidates of the detector's candidates (each refined from its pose and
  /// from its template's) end on it within the confirm limits, held too; it is confirmed on the
  /// next frame at that share. A partly hidden object, a third of its edges hidden, is held at
  /// 0.55-0.6 of its samples, under the share a single start needs (top_evidence, accept_evidence),
  /// while candidates starting up to 15 degrees off fall into its basin; one clutter rarely draws
  /// three. < 2: off.
  int consensus_candidates = 3;
  double consensus_evidence = 0.5;
  /// Of two poses accepted on one search frame over the same place (each centre within the
  /// model's bounding radius of the other's ray), one whose outline leaks the object's own
  /// colours (features::SilhouetteContrast) by this share more than the other's is dropped: its
  /// outline lies on the object's faces, a pose nested inside the real one (a textured box
  /// fitted smaller and farther, its top edge on a band of its texture). Needs
  /// status.leak_min_samples colour samples on both; 1: off.
  double nested_leak_margin = 0.2;
  /// `v4r serve`: the expensive search runs on a worker thread of its own, on a copy of the
  /// newest camera-0 image (pipeline::BackgroundSearch), so that the other objects' cycles keep
  /// their budget; false: on the cycle's thread after each cycle, as `v4r track` always does.
  bool background = true;
  detection::TagParams tag;  ///< search.tag.*: the optional AprilTag start (set_tag_start)
};

/// Registers every ObjectSearchParams field under `search.*` (units and ranges); `p` must
/// outlive the registry.
void add_search_params(ParamRegistry& r, ObjectSearchParams& p);

/// \brief What the search did for one object on one frame.
struct SearchReport {
  bool searched = false;     ///< the object was searched on this frame
  bool found = false;        ///< a hypothesis was accepted (a candidate, not yet confirmed)
  bool locked = false;       ///< a candidate was confirmed: the object is `tracking` from this frame
  bool started = false;      ///< the object turned to `searching` on this frame (lost for lost_frames)
  int tried = 0;             ///< hypotheses refined by the tracker
  double best_evidence = 0;  ///< edge evidence of the best refined hypothesis
  double search_ms = 0.0;    ///< time of this object's search
  double detect_ms = 0.0;    ///< of which the detector's whole-image search
  int tag_poses = 0;         ///< poses of the object's AprilTag refined (0: no tag set, or not seen)
  int tag_vetoed = 0;        ///< refined poses refused because they put the seen tag elsewhere
  bool cancelled = false;    ///< a stop request cut the search short (BackgroundSearch shutting down)
};

/// \brief Where and how an object was last seen (the start of the restarts of a search).
struct LastSeen {
  geometry::SE3 T_cam_obj;  ///< camera 0's frame
  geometry::Vector6d velocity = geometry::Vector6d::Zero();  ///< (v, w) left tangent, camera 0's frame, m/s, rad/s
  double stamp_s = -1.0;    ///< time of T_cam_obj and velocity (< 0: no velocity known)
  double leak_typical = -1.0;  ///< the object's silhouette leak while tracked (scene::Object::leak_typical; < 0: unknown)
};

/// \brief What the cheap per-frame bookkeeping (search_step) says about one searchable object.
enum class SearchStep {
  kWaiting,  ///< lost, but not yet for lost_frames frames in a row (or the search is disabled)
  kStarted,  ///< turned to `searching` on this frame (lost for lost_frames frames)
  kSearch,   ///< searching: to be searched on this frame
  kIdle,     ///< neither lost nor searching: a candidate it had is dropped
};

/// The bookkeeping of one object on one frame, after VisionCycle::process (cheap: on the
/// cycle's thread): counts the frames in a row the object was reported `lost` in `lost_streak`;
/// at p.lost_frames (with p.enabled) the object turns to `searching` (Scene::start_search) and
/// `last` receives where it was last seen: the last pose reported `tracking` and the velocity
/// then (else the pose held while lost, velocity unknown). Allocates nothing.
SearchStep search_step(const ObjectSearchParams& p, scene::Scene& scene, std::size_t object, int& lost_streak,
                       LastSeen& last);

/// \brief A pose one search frame accepted, with what the choice among them needs.
struct FoundPose {
  geometry::SE3 T_cam_obj;
  double rank = 0.0;      ///< edge samples the image confirms, weighed (the search's ranking)
  double evidence = 0.0;  ///< share of the projected model's edge samples confirmed
  double leak = -1.0;     ///< share of its outline's outside colour samples like the object's (< 0: none)
  int leak_samples = 0;   ///< colour samples of the leak
  bool local = false;     ///< a restart around the last pose (else a candidate, tag or detector pose)
  double accept = 0.0;    ///< the evidence share its confirmation on the next frame needs (less confirm_margin)
};

/// \brief What the choice among found poses knows of the object (see choose_found_pose).
struct NestingTest {
  double margin = 1.0;             ///< ObjectSearchParams::nested_leak_margin (1: off)
  double leak_typical = -1.0;      ///< the object's silhouette leak while tracked (< 0: unknown, off)
  double leak_max_typical = 0.25;  ///< StatusParams::leak_max_typical
  double leak_margin = 0.15;       ///< StatusParams::leak_margin
  int leak_min_samples = 12;       ///< StatusParams::leak_min_samples
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< the model's bounding sphere, object frame
  double radius = 0.0;                               ///< ... and its radius, m
};

/// True when T_cam_obj puts the bounding sphere's centre within its radius, as seen from the
/// camera, of where T_other puts it (their rays closer than the radius at T_other's distance).
[[nodiscard]] bool over_place(const geometry::SE3& T_cam_obj, const geometry::SE3& T_other,
                              const Eigen::Vector3d& centre, double radius);

/// The found pose a search frame takes: the highest rank, except that a pose nested in another
/// gives way to it however many edge samples it explains. Nested: both over the same place
/// (over_place both ways), its outline leaks the object's colours by more than t.margin over the
/// other's, and the other leaks about as little as the object did while tracked (at most
/// leak_typical + leak_margin); each from leak_min_samples colour samples. Only for an object that
/// stood out from its surroundings while tracked (leak_typical in [0, leak_max_typical]): its
/// outline then lay on the background, a nested pose's lies on the object's own faces (a
/// textured box fitted smaller and farther, an edge on a band of its texture). Returns the index
/// in `found`, -1 when it is empty. Allocates nothing.
[[nodiscard]] int choose_found_pose(std::span<const FoundPose> found, const NestingTest& t);

/// Sets a pose the search found and confirmed: T_cam_obj (camera 0's frame) becomes the object's
/// pose (Scene::set_pose), `tracking`, with `evidence` as its evidence and quality.
void set_found_pose(scene::Scene& scene, std::size_t object, const geometry::SE3& T_cam_obj, double evidence);

/// \brief Finds objects that have no pose (kSearching) and hands them back to the vision cycle.
///
/// Per frame, after VisionCycle::process: an object reported `lost` for lost_frames frames in a
/// row turns to `searching`. A searching object is looked for on camera 0: (1) the candidate of
/// the last frame, if any, tracked on this frame; (2) with set_tag_start, both poses of the
/// object's AprilTag; unless one of them was accepted: (3) on the first local_frames search
/// frames, perturbed restarts around the last pose (accepted at local_accept_evidence); unless one
/// of them was accepted: (4) the detector's best hypotheses over the whole image
/// (detection::Detector), from their refined poses and from their templates' poses
/// (template_starts), and with none of those accepted, a pose several of them end on
/// (consensus_candidates). Every hypothesis is refined by the tracker itself (a private
/// VisionCycle run refine_cycles times on it: features not found yet are searched in the wide
/// window, then tracked in the normal one) and accepted by the cycle's own status test: the
/// share of the whole projected model's edge samples that the image confirms
/// (features::EdgeEvidence; the detector's own verification score is not used). The highest
/// ranked (choose_found_pose) is put to the detector's twin test when the model has
/// near-symmetric twins (Detector::prefer_twin: that evidence hardly tells them apart). An accepted
/// pose confirmed on the next frame (consistency over 2 frames: tracked there within the confirm
/// limits, or tracked near them and found again by that frame's search) is set on the scene
/// object, which is `tracking` from then on. Set-up allocates; update() throws nothing and allocates
/// nothing, except in the tag detection of (2) (libapriltag, on search frames only). Not thread-safe.
class ObjectSearch {
 public:
  ObjectSearch(const CycleParams& cycle, const ObjectSearchParams& p, const detection::DetectorParams& dp);

  /// Makes scene object `object` searchable with the templates of its model for camera 0 of the
  /// scene (built by detection::load_or_build for that camera and `dp`). Allocates.
  void add_object(const scene::Scene& scene, std::size_t object,
                  std::shared_ptr<const detection::TemplateSet> templates);

  /// Gives a searchable object (add_object first) an AprilTag fixed on it: while the object is
  /// searched, both poses of the tag (detection::TagStart) are refined and tested like the
  /// detector's hypotheses, before them; when one is accepted, the restarts and the detector are
  /// skipped on that frame. While the tag is seen, any pose (a candidate's, a restart's, the
  /// detector's) must also put the tag where it is seen (search.tag.max_offset). Once found, the
  /// object is tracked without the tag. Tag detection allocates (libapriltag): search frames only.
  void set_tag_start(std::size_t object, std::unique_ptr<detection::TagStart> tag);

  /// Runs the search for this frame (see the class comment); `images` as given to the cycle.
  /// Returns one report per scene object (objects without templates are never searched).
  std::span<const SearchReport> update(scene::Scene& scene, std::span<const CameraImage> images, double stamp_s);

  // The parts of update(), for a search that runs away from the scene (BackgroundSearch): they
  // never touch a scene, so that they can run on a worker thread on copies of the images.

  /// True when `object` was made searchable (add_object).
  [[nodiscard]] bool searchable(std::size_t object) const;
  /// A search of `object` begins: its candidate is dropped; perturbed restarts are tried around
  /// where it was last seen (and where its velocity then takes it) on the first local_frames
  /// search frames, none if null.
  void begin_search(std::size_t object, const LastSeen* last);
  /// `object` is not searched any more (found, or given a pose): its candidate is dropped.
  void end_search(std::size_t object);
  /// Searches `object` (searchable) on one frame: steps (1)-(4) of the class comment. When a
  /// candidate was confirmed (report `locked`), `T_cam_found` receives its pose (camera 0's
  /// frame) and report best_evidence its evidence; the search of this object then ends. A stop
  /// request skips the hypotheses not yet refined (report `cancelled`). Allocates nothing and
  /// throws nothing (except for the tag detection, see set_tag_start).
  SearchReport search_frame(std::size_t object, const CameraImage& img, double stamp_s, geometry::SE3& T_cam_found,
                            std::stop_token stop = {});

  [[nodiscard]] const ObjectSearchParams& params() const { return p_; }

 private:
  struct Slot {
    bool active = false;
    std::unique_ptr<detection::Detector> detector;
    int lost_streak = 0;
    int search_frames = 0;
    bool have_last = false;      // a last pose to restart from (camera frame)
    geometry::SE3 T_last;
    geometry::Vector6d v_last = geometry::Vector6d::Zero();  // velocity at T_last (camera frame)
    double stamp_last = -1.0;    // time of T_last and v_last (< 0: no velocity)
    double leak_typical = -1.0;  // silhouette leak while tracked (< 0: unknown)
    geometry::SE3 T_leak;        // the last tracked pose, where leak_typical holds
    bool have_candidate = false; // accepted on the previous frame, to be confirmed
    geometry::SE3 T_candidate;
    bool candidate_local = false;  // the candidate came from a restart around the last pose
    double candidate_accept = 0.0;  // the evidence share it was accepted at (its confirmation's)
    double candidate_evidence = 0.0;  // its evidence share when found
    double radius = 0.0;         // model bounding radius, m
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    detection::ViewRange range;  // resolved for the model and camera
    std::vector<geometry::SE3> symmetries;
    std::unique_ptr<detection::TagStart> tag;  // optional fiducial
  };
  /// T_cam_obj (or one of its symmetric equivalents) within the slot's view range and margin.
  [[nodiscard]] bool in_view_range(const Slot& s, const geometry::SE3& T) const;
  /// T_cam_obj puts the object's centre within its bounding radius (as seen from the camera) of
  /// where T_other puts it.
  [[nodiscard]] static bool over_place(const Slot& s, const geometry::SE3& T, const geometry::SE3& T_other);
  /// Refines T (camera frame) with the private cycle; returns its rank (edge samples the image
  /// confirms) if accepted, else -1; its edge evidence (share) in last_evidence_. A `degraded`
  /// status counts as tracked when degraded_ok (a confirmation); last_degraded_ tells which.
  /// from_this_image: T was measured on this image (a detector hypothesis or its template's
  /// pose, a tag's), so the cycle treats it as confirmed and its per-sample fit runs from the
  /// first cycle; else (a restart, last frame's candidate) as a pose just set.
  double refine(std::size_t object, const CameraImage& img, double stamp_s, geometry::SE3& T, double accept_evidence,
                bool degraded_ok, bool from_this_image);

  ObjectSearchParams p_;
  detection::DetectorParams dp_;
  VisionCycle probe_;             // the tracker run on hypotheses
  scene::Scene probe_scene_;      // camera 0 at the reference, one object per scene object
  std::vector<Slot> slots_;
  std::vector<SearchReport> reports_;
  std::vector<detection::Hypothesis> hyp_;
  /// The detector's gradients of this search frame's image, computed once per frame when first
  /// needed (false: the detector refused the image).
  bool gradients_for(Slot& s, const CameraImage& img);
  /// The detector's edge test of a refined pose on this search frame's image.
  bool edge_test(Slot& s, const CameraImage& img, const geometry::SE3& T);
  std::uint64_t search_frame_id_ = 0;  // search_frame calls so far
  std::uint64_t gradients_id_ = 0;     // the call whose image the detector's gradients are of (0: none)
  double last_evidence_ = 0.0;
  bool last_degraded_ = false;    // the last refined pose was reported `degraded`
  bool last_held_ = false;        // the last refined pose was held by the tracker (tracked, see refine)
  double last_rank_ = 0.0;        // ... its rank, accepted or not
  double last_leak_ = -1.0;       // the last refined pose's silhouette leak (-1: no colour samples)
  int last_leak_samples_ = 0;
  std::vector<FoundPose> accepted_;  // this frame's accepted poses (capacity fixed at construction)
  /// This frame's detector starts, refined: where they ended, whether the tracker held them there,
  /// and the candidate they started from.
  struct Refined {
    FoundPose found;
    bool held = false;
    int candidate = 0;
  };
  std::vector<Refined> refined_;  // (capacity fixed at construction)
  /// consensus_candidates: adds to accepted_ the held poses enough candidates' starts end on.
  void take_consensus();
};

}  // namespace v4r::pipeline
