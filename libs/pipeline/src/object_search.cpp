// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/object_search.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

#include "v4r/detection/symmetry.hpp"
#include "v4r/detection/view_range.hpp"
#include "v4r/geometry/se3_jacobians.hpp"

namespace v4r::pipeline {

namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

/// The cycle that refines hypotheses: no filter (each frame's pose is its measurement), no budget.
CycleParams probe_params(const CycleParams& c) {
  CycleParams p = c;
  p.use_filter = false;
  p.smooth_output = false;
  p.budget.cycle_ms = 0.0;
  // A pair of close edges is measured at its visible edge, not at the centre between the two
  // strongest edges of opposite sign (cycle.pair_span): refined from a detector hypothesis,
  // wherever it lies, that centre locked more wrong poses and found no more right ones (the
  // section, 120 blurred renders: 97 found either way, wrong 8 -> 11; 120 occluded: 91 -> 92
  // found; the ship, 40 a cell: 4 fewer found, 1 plain image wrong).
  p.pair_span_px = 0.0;
  // The per-sample fit wherever the line solve leaves an edge unused, however well the image
  // confirms its pose (samples.doubt_evidence: a cap for the real-time cycle's sake): with the cap,
  // 2 of 120 blurred box renders were no longer found (119 -> 117).
  p.samples.doubt_evidence = 1.0;
  // Each refinement's outline is tested for leaks: its last cycle's colour samples (refine()
  // sets the wait to that cycle).
  p.status.leak_period = 1;
  return p;
}

/// Pose T within `factor` times the search's confirm limits of T_other.
bool within_confirm_limits(const ObjectSearchParams& p, const geometry::SE3& T, const geometry::SE3& T_other,
                           double factor) {
  return (T.translation() - T_other.translation()).norm() <= factor * p.confirm_translation_m &&
         geometry::rotation_angle_between(T, T_other) <= factor * p.confirm_rotation_deg * kDeg;
}

}  // namespace

void add_search_params(ParamRegistry& r, ObjectSearchParams& p) {
  r.add("search.enabled", &p.enabled, "search objects without a pose (start, and after lost_frames lost frames)");
  r.add("search.lost_frames", &p.lost_frames, 1, 100000, "frames", "frames reported lost in a row before the object is searched again");
  r.add("search.local_frames", &p.local_frames, 0, 100000, "frames",
        "search frames on which perturbed restarts around the last pose are tried");
  r.add("search.restarts", &p.restarts, 0, 64, "",
        "perturbed restarts around the last pose (and around the extrapolated one) per search frame");
  r.add("search.extrapolate_s", &p.extrapolate_s, 0.0, 100.0, "s",
        "restarts also where the velocity at the last tracked frame takes the object, extrapolated at most this long (0: off)");
  r.add("search.restart_shift", &p.restart_shift, 0.0, 10.0, "radius",
        "restart offsets across the view, in model bounding radii");
  r.add("search.hypotheses", &p.hypotheses, 1, 64, "", "best detector hypotheses refined by the tracker per search frame");
  r.add("search.template_starts", &p.template_starts,
        "each of those is also refined from its template's pose (before the detector's own alignment, which texture can pull away)");
  r.add("search.refine_cycles", &p.refine_cycles, 1, 20, "", "vision cycles run on a hypothesis (wide windows, then normal)");
  r.add("search.accept_evidence", &p.accept_evidence, 0.0, 1.0, "",
        "share of the projected model's edge samples the image must confirm for a found pose");
  r.add("search.local_accept_evidence", &p.local_accept_evidence, 0.0, 1.0, "",
        "the same for a restart around the last tracked pose (then the whole image is not searched on that frame)");
  r.add("search.edge_test_evidence", &p.edge_test_evidence, 0.0, 1.0, "",
        "below its accept share but at least this, a found pose is accepted when the detector's edge test verifies it (>= accept_evidence: off)");
  r.add("search.stand_out_evidence", &p.stand_out_evidence, 0.0, 1.0, "",
        "a detector pose verified by its colour (the colour test or the stand-out verdict; a partly hidden object) is accepted at "
        "this share, when the tracker keeps it within the confirm limits (>= accept_evidence: off)");
  r.add("search.top_evidence", &p.top_evidence, 0.0, 1.0, "",
        "with no detector pose verified, the best-scoring one (edge score at least search.top_score) is accepted at this share when "
        "the tracker keeps it within the confirm limits, and confirmed at the usual share (>= accept_evidence: off)");
  r.add("search.top_score", &p.top_score, 0.0, 1.0, "", "... the detector's edge score it needs (detect.verify: share of samples in runs)");
  r.add("search.view_margin", &p.view_margin_deg, 0.0, 180.0, "deg",
        "a found pose must lie in the detector's view range (detect.views.*) widened by this");
  r.add("search.confirm_translation", &p.confirm_translation_m, 0.0, 10.0, "m",
        "a found pose is confirmed when the next frame finds it again this close");
  r.add("search.confirm_rotation", &p.confirm_rotation_deg, 0.0, 180.0, "deg", "... and within this angle");
  r.add("search.confirm_margin", &p.confirm_margin, 0.0, 1.0, "",
        "the next frame confirms a found pose at the evidence share it was accepted at, less this");
  r.add("search.confirm_degraded", &p.confirm_degraded, 0.0, 1.0, "",
        "a confirmation reported degraded still confirms within this share of the confirm limits, at the share the pose was "
        "accepted at (0: off)");
  r.add("search.refound_factor", &p.refound_factor, 0.0, 10.0, "",
        "a found pose tracked beyond the confirm limits but within this factor of them, to no better support, is confirmed "
        "when the frame's own search finds it again within the limits (<= 1: off)");
  r.add("search.rank_evidence_power", &p.rank_evidence_power, 0.0, 10.0, "",
        "found poses are ranked by their confirmed edge samples times their evidence share to this power");
  r.add("search.consensus_candidates", &p.consensus_candidates, 0, 64, "",
        "with no pose accepted, a pose held at search.consensus_evidence is accepted when starts from this many of the "
        "detector's candidates end on it (< 2: off)");
  r.add("search.consensus_evidence", &p.consensus_evidence, 0.0, 1.0, "",
        "... the share of its edge samples confirmed it needs, on the frame found and the next");
  r.add("search.nested_leak_margin", &p.nested_leak_margin, 0.0, 1.0, "",
        "of two poses found over the same place, one whose outline leaks the object's colours by this share more is dropped (1: off)");
  r.add("search.background", &p.background,
        "v4r serve: search on a worker thread of its own with the newest image (false: on the cycle's thread)");
  detection::add_tag_params(r, p.tag, "search.tag");
}

ObjectSearch::ObjectSearch(const CycleParams& cycle, const ObjectSearchParams& p, const detection::DetectorParams& dp)
    : p_(p), dp_(dp), probe_(probe_params(cycle)) {
  hyp_.resize(static_cast<std::size_t>(std::clamp(p_.hypotheses, 1, 64)));
  // Every pose one search frame can accept: the candidate, two tag poses, the restarts around
  // two centres (at most 9 each) and the detector's hypotheses (refined and their templates).
  accepted_.reserve(1 + 2 + 2 * 9 + 2 * hyp_.size());
  refined_.reserve(2 * hyp_.size());  // (at most 64 candidates: take_consensus counts them in 64 bits)
}

void ObjectSearch::add_object(const scene::Scene& scene, std::size_t object,
                              std::shared_ptr<const detection::TemplateSet> templates) {
  if (object >= scene.objects().size() || scene.cameras().empty() || !templates) return;
  if (probe_scene_.cameras().empty()) {
    scene::Camera c = scene.cameras()[0];
    c.T_ref_cam = geometry::SE3();
    probe_scene_.add_camera(c);
  }
  // One probe object per scene object (same index), added up to `object`.
  const auto& objs = scene.objects();
  while (probe_scene_.objects().size() <= object) {
    const std::size_t k = probe_scene_.objects().size();
    (void)probe_scene_.add_object(objs[k].name, objs[k].model);
  }
  if (slots_.size() < objs.size()) slots_.resize(objs.size());
  if (reports_.size() < objs.size()) reports_.resize(objs.size());
  Slot& s = slots_[object];
  // The search confirms hypotheses itself (tracked, evidence over two frames, its own leak test).
  // A pose the detector verifies by its colour (its colour test or its stand-out verdict, the
  // edge score below accept_score: a partly hidden object) needs a lower evidence share
  // (stand_out_evidence). Off, the search takes the detector's ranking by the edge test alone, as
  // it did when the colour test moved a nested pose ahead of the truth on box_occlusion
  // (benchmark; with the detector's later nested-pose rules it no longer does: without an initial
  // pose that sequence locks at frame 1 either way).
  detection::DetectorParams search_dp = dp_;
  if (p_.stand_out_evidence >= p_.accept_evidence) {
    search_dp.verify.leak_score = 1.0;
    search_dp.verify.stand_out_score = 1.0;
  }
  s.detector = std::make_unique<detection::Detector>(objs[object].model, std::move(templates),
                                                     scene.cameras()[0].intrinsics, search_dp);
  const detection::ModelExtent ext = detection::model_extent(*objs[object].model);
  s.radius = ext.radius;
  s.centre = ext.centre;
  s.range = detection::resolve_view_range(dp_.views, ext.radius, scene.cameras()[0].intrinsics.focal());
  s.symmetries = detection::model_symmetries(*objs[object].model);
  if (s.symmetries.empty()) s.symmetries.emplace_back();
  s.active = true;
  // Allocate the probe cycle's buffers now (a cycle on an empty image set allocates them).
  probe_.process(probe_scene_, {}, 0.0);
}

void ObjectSearch::set_tag_start(std::size_t object, std::unique_ptr<detection::TagStart> tag) {
  if (object < slots_.size() && slots_[object].active) slots_[object].tag = std::move(tag);
}

bool ObjectSearch::in_view_range(const Slot& s, const geometry::SE3& T) const {
  return detection::in_view_range(s.range, s.centre, s.symmetries, T, p_.view_margin_deg, p_.view_margin_deg);
}

bool over_place(const geometry::SE3& T_cam_obj, const geometry::SE3& T_other, const Eigen::Vector3d& centre,
                double radius) {
  const Eigen::Vector3d c_other = T_other * centre;
  const Eigen::Vector3d c = T_cam_obj * centre;
  const double d = c_other.norm();
  if (d <= radius || c.norm() <= 1e-9) return true;  // (the camera inside the bounding sphere)
  return c.normalized().dot(c_other / d) >= std::sqrt(1.0 - (radius / d) * (radius / d));
}

int choose_found_pose(std::span<const FoundPose> found, const NestingTest& t) {
  const bool test = t.margin < 1.0 && t.leak_typical >= 0.0 && t.leak_typical <= t.leak_max_typical;
  const auto nested = [&](const FoundPose& a) {
    if (!test || a.leak_samples < t.leak_min_samples) return false;
    for (const FoundPose& b : found)
      if (b.leak_samples >= t.leak_min_samples && b.leak <= t.leak_typical + t.leak_margin && b.leak + t.margin < a.leak &&
          over_place(a.T_cam_obj, b.T_cam_obj, t.centre, t.radius) && over_place(b.T_cam_obj, a.T_cam_obj, t.centre, t.radius))
        return true;
    return false;
  };
  int best = -1;
  for (std::size_t k = 0; k < found.size(); ++k)
    if ((best < 0 || found[k].rank > found[static_cast<std::size_t>(best)].rank) && !nested(found[k]))
      best = static_cast<int>(k);
  return best;
}

bool ObjectSearch::over_place(const Slot& s, const geometry::SE3& T, const geometry::SE3& T_other) {
  return pipeline::over_place(T, T_other, s.centre, s.radius);
}

double ObjectSearch::refine(std::size_t object, const CameraImage& img, double stamp_s, geometry::SE3& T,
                            double accept_evidence, bool degraded_ok, bool from_this_image) {
  if (T.translation().z() <= 1e-3) return -1.0;
  probe_scene_.set_pose(object, T);
  scene::Object& o = probe_scene_.objects()[object];
  // (The probe runs no filter: `confirmed` lets the per-sample fit run, no prior.)
  o.confirmed = from_this_image;
  // Only the last cycle's outline is read (its leak, below): its colours are sampled then only.
  o.leak_wait = std::max(1, p_.refine_cycles) - 1;
  for (int c = 0; c < std::max(1, p_.refine_cycles); ++c) {
    probe_.process(probe_scene_, std::span<const CameraImage>(&img, 1), stamp_s);
    if (o.status == scene::TrackStatus::kUninitialised) break;  // (a fault in the probe: give up on it)
  }
  const Slot& slot = slots_[object];
  // Its outline must not leak the object's own colours much more than while the object was
  // tracked (the outline on texture: a pose nested in the real one). The typical leak belongs to
  // the faces and background seen then: it is used where the object is found over the place it
  // was last tracked (centres' rays within its bounding radius), as after an occlusion.
  const StatusParams& sp = probe_.params().status;
  const bool leaks = slot.leak_typical >= 0.0 && slot.leak_typical <= sp.leak_max_typical && o.leak_samples >= sp.leak_min_samples && sp.leak_margin < 1.0 &&
                     o.leak > slot.leak_typical + sp.leak_margin && over_place(slot, o.T_ref_obj, slot.T_leak);
  last_degraded_ = o.status == scene::TrackStatus::kDegraded;
  const bool tracked = (o.status == scene::TrackStatus::kTracking || (degraded_ok && last_degraded_)) && !leaks &&
                       in_view_range(slot, o.T_ref_obj);
  const bool ok = tracked && (o.evidence >= accept_evidence ||
                              (o.evidence >= p_.edge_test_evidence && edge_test(slots_[object], img, o.T_ref_obj)));
  // Rank: edge samples confirmed, times their share to the power rank_evidence_power, weighed
  // down by the pose solve's RMS residual as the cycle's quality is (1 / (1 + (rms / 1.5 px)^2)).
  // An edge image can be fitted by more than one pose of a box (a Necker-like reversal: turned
  // and farther, its projected edges on the image's edges and on texture): the false one explains
  // as many samples or more, but leaves more of its own unconfirmed or fits them only to a pixel
  // or so. A pose fitted to clutter, larger than the object, may also explain more samples.
  int matched = 0;
  for (const scene::View& v : o.views) matched += v.evidence_matched;
  const double rms = probe_.last_report().objects[object].rms_px;
  const double rank = matched * std::pow(o.evidence, p_.rank_evidence_power) / (1.0 + (rms / 1.5) * (rms / 1.5));
  last_held_ = tracked;
  last_rank_ = rank;
  last_evidence_ = o.evidence;
  last_leak_ = o.leak;
  last_leak_samples_ = o.leak_samples;
  T = o.T_ref_obj;
  o.status = scene::TrackStatus::kUninitialised;  // the probe object rests until the next hypothesis
  return ok ? rank : -1.0;
}

bool ObjectSearch::gradients_for(Slot& s, const CameraImage& img) {
  if (gradients_id_ != search_frame_id_) {
    const bool ok = img.colour.empty() ? s.detector->set_image(img.grey) : s.detector->set_image(img.colour);
    if (!ok) return false;
    gradients_id_ = search_frame_id_;
  }
  return true;
}

bool ObjectSearch::edge_test(Slot& s, const CameraImage& img, const geometry::SE3& T) {
  if (!s.detector || !gradients_for(s, img)) return false;
  const detection::Verification v = s.detector->verify(T);
  const detection::VerifyParams& vp = s.detector->params().verify;
  return v.samples >= vp.min_samples && v.score >= vp.accept_score;
}

bool ObjectSearch::searchable(std::size_t object) const { return object < slots_.size() && slots_[object].active; }

void ObjectSearch::begin_search(std::size_t object, const LastSeen* last) {
  if (!searchable(object)) return;
  Slot& s = slots_[object];
  s.have_last = last != nullptr;
  s.stamp_last = -1.0;
  s.leak_typical = last ? last->leak_typical : -1.0;
  if (last) s.T_leak = last->T_cam_obj;
  if (last) {
    s.T_last = last->T_cam_obj;
    s.v_last = last->velocity;
    s.stamp_last = last->stamp_s;
  }
  s.have_candidate = false;
  s.search_frames = 0;
}

void ObjectSearch::end_search(std::size_t object) {
  if (searchable(object)) slots_[object].have_candidate = false;
}

SearchReport ObjectSearch::search_frame(std::size_t object, const CameraImage& img, double stamp_s,
                                        geometry::SE3& T_cam_found, std::stop_token stop) {
  SearchReport rep;
  if (!searchable(object) || img.grey.empty()) return rep;
  Slot& s = slots_[object];
  const auto t0 = Clock::now();
  rep.searched = true;
  ++s.search_frames;
  ++search_frame_id_;
  accepted_.clear();
  // The object's tag, if given and seen: a pose of the object must put it where it is seen.
  const detection::TagObservation tag = s.tag ? s.tag->detect(img.grey) : detection::TagObservation{};
  const auto within = [&](const geometry::SE3& T, const geometry::SE3& T_other, double factor) {
    return within_confirm_limits(p_, T, T_other, factor);
  };
  int start_candidate = -1;  // >= 0: the poses considered start from this candidate of the detector's (kept in refined_)
  refined_.clear();
  // A pose refined and, if accepted at the share `accept`, kept with the share its confirmation
  // needs (`confirm_at`; < 0: `accept`).
  const auto consider = [&](geometry::SE3 T, bool local, double accept, bool by_colour = false, bool degraded_ok = false,
                            double confirm_at = -1.0, bool from_this_image = true) {
    if (stop.stop_requested()) {  // shutting down: the hypotheses left are not refined
      rep.cancelled = true;
      return -1.0;
    }
    ++rep.tried;
    const geometry::SE3 T_start = T;
    double e = refine(object, img, stamp_s, T, accept, degraded_ok, from_this_image && !local);
    // A pose verified by its colour, accepted below the usual share: the refinement must keep it.
    if (e >= 0.0 && by_colour && last_evidence_ < p_.accept_evidence && !within(T, T_start, 1.0)) e = -1.0;
    // With the tag seen, the pose must put it where it is seen.
    const bool tag_ok = !tag.found || s.tag->corner_offset_px(tag, T) <= p_.tag.max_offset_px;
    if (e >= 0.0 && !tag_ok) {
      e = -1.0;
      ++rep.tag_vetoed;
    }
    if (e >= 0.0 && accepted_.size() < accepted_.capacity())
      accepted_.push_back({T, e, last_evidence_, last_leak_, last_leak_samples_, local, confirm_at >= 0.0 ? confirm_at : accept});
    if (start_candidate >= 0 && refined_.size() < refined_.capacity())
      refined_.push_back({FoundPose{T, last_rank_, last_evidence_, last_leak_, last_leak_samples_, false,
                                    p_.consensus_evidence + p_.confirm_margin},
                          last_held_ && tag_ok, start_candidate});
    return e;
  };
  // A pose confirmed: the object is `tracking` there from this frame on.
  const auto lock = [&](const geometry::SE3& T, double evidence) {
    // A symmetric object is reported in the equivalent pose nearest to where it was last seen.
    T_cam_found = s.have_last ? detection::nearest_symmetric(T, s.T_last, s.symmetries) : T;
    s.have_candidate = false;
    s.have_last = true;
    s.T_last = T_cam_found;
    s.stamp_last = -1.0;
    s.search_frames = 0;
    rep.found = rep.locked = true;
    rep.best_evidence = evidence;
  };
  // (1) Last frame's candidate, tracked on this frame: confirmed when it stays put.
  bool refound = false;  // ... or when this frame's search finds it again (see refound_factor)
  geometry::SE3 T_last_candidate;
  if (s.have_candidate) {
    double e = consider(s.T_candidate, s.candidate_local, s.candidate_accept - p_.confirm_margin, false,
                        p_.confirm_degraded > 0.0, -1.0, false);
    const geometry::SE3 T = e >= 0.0 ? accepted_.back().T_cam_obj : s.T_candidate;  // refined
    // A `degraded` confirmation: closer, and at the share the pose was accepted at; else it is no
    // found pose of this frame.
    if (e >= 0.0 && last_degraded_ &&
        (last_evidence_ < s.candidate_accept || !within(T, s.T_candidate, p_.confirm_degraded))) {
      e = -1.0;
      accepted_.pop_back();
    }
    if (e >= 0.0 && within(T, s.T_candidate, 1.0)) {
      lock(T, accepted_.back().evidence);
      rep.search_ms = ms_between(t0, Clock::now());
      return rep;
    }
    refound = e >= 0.0 && p_.refound_factor > 1.0 && last_evidence_ <= s.candidate_evidence &&
              within(T, s.T_candidate, p_.refound_factor);
    T_last_candidate = s.T_candidate;
  }
  // (2) The AprilTag on the object, if given: both poses of the square. One accepted makes the
  // restarts and the whole-image detector unnecessary on this frame.
  bool tag_accepted = false;
  for (int k = 0; k < tag.poses; ++k) {
    ++rep.tag_poses;
    if (consider(tag.T_cam_obj[static_cast<std::size_t>(k)], false, p_.accept_evidence) >= 0.0) tag_accepted = true;
  }
  // (3) Perturbed restarts around the last pose (first search frames after a loss); one accepted
  // makes the whole-image detector unnecessary on this frame.
  bool local_accepted = false;
  if (!tag_accepted && s.have_last && s.search_frames <= p_.local_frames) {
    const double d = p_.restart_shift * s.radius;
    const Eigen::Vector3d shifts[] = {{0, 0, 0}, {d, 0, 0}, {-d, 0, 0}, {0, d, 0}, {0, -d, 0}, {d, d, 0}, {-d, -d, 0},
                                      {d, -d, 0}, {-d, d, 0}};
    const int n = std::min<int>(p_.restarts + 1, static_cast<int>(std::size(shifts)));
    // Around the last pose, and around where the velocity then takes the object by now.
    const double dt = s.stamp_last >= 0.0 ? std::min(stamp_s - s.stamp_last, p_.extrapolate_s) : 0.0;
    const bool moving = dt > 0.0 && (s.v_last * dt).head<3>().norm() > 0.25 * d;
    const geometry::SE3 centres[] = {s.T_last, moving ? geometry::SE3::exp(s.v_last * dt) * s.T_last : s.T_last};
    for (int c = 0; c < (moving ? 2 : 1); ++c)
      for (int k = 0; k < n; ++k)
        if (consider(geometry::SE3(Eigen::Quaterniond::Identity(), shifts[k]) * centres[c], true, p_.local_accept_evidence) >= 0.0)
          local_accepted = true;
  }
  // (4) The detector over the whole image.
  if (!tag_accepted && !local_accepted && !stop.stop_requested()) {
    const auto td = Clock::now();
    const detection::DetectionResult r =
        img.colour.empty() ? s.detector->detect(img.grey, hyp_) : s.detector->detect(img.colour, hyp_);
    // Its gradients are this image's, unless the colour stage computed them around its regions only.
    gradients_id_ = r.status == detection::DetectionResult::Status::kOk && r.colour_regions < 0 ? search_frame_id_ : 0;
    rep.detect_ms = ms_between(td, Clock::now());
    if (r.status == detection::DetectionResult::Status::kOk) {
      const int n = std::min<int>(r.hypotheses, std::min<int>(p_.hypotheses, static_cast<int>(hyp_.size())));
      const double accept_score = s.detector->params().verify.accept_score;
      for (int k = 0; k < n; ++k) {
        const detection::Hypothesis& h = hyp_[static_cast<std::size_t>(k)];
        const bool by_colour = h.verified && h.verification.score < accept_score;
        // Nothing verified: the best-scoring pose (first), at top_evidence, kept in place by the
        // tracker like a colour-verified one, and confirmed at the usual share.
        const bool top = k == 0 && r.verified == 0 && p_.top_evidence < p_.accept_evidence && h.verification.score >= p_.top_score;
        const double accept = by_colour ? std::min(p_.stand_out_evidence, p_.accept_evidence) : top ? p_.top_evidence : p_.accept_evidence;
        start_candidate = k;
        consider(h.T_cam_obj, false, accept, by_colour || top, false, top ? p_.accept_evidence : -1.0);
      }
      if (p_.template_starts)
        for (int k = 0; k < n; ++k) {
          start_candidate = k;
          consider(hyp_[static_cast<std::size_t>(k)].T_template, false, p_.accept_evidence);
        }
      start_candidate = -1;
      if (accepted_.empty()) take_consensus();
    }
  }
  // The highest rank, unless it is nested in another accepted pose (choose_found_pose).
  const StatusParams& sp = probe_.params().status;
  const NestingTest t{p_.nested_leak_margin, s.leak_typical, sp.leak_max_typical, sp.leak_margin,
                      sp.leak_min_samples,   s.centre,       s.radius};
  const int k = choose_found_pose(accepted_, t);
  s.have_candidate = k >= 0;
  rep.best_evidence = 0.0;
  if (s.have_candidate) {
    const FoundPose& f = accepted_[static_cast<std::size_t>(k)];
    s.T_candidate = f.T_cam_obj;
    // The tracker's evidence hardly tells a near-symmetric twin (the section turned half round,
    // its walls' heights swapped) from the pose: the detector's twin test does.
    if (s.detector && s.detector->has_twins() && gradients_for(s, img)) s.detector->prefer_twin(s.T_candidate);
    s.candidate_local = f.local;
    s.candidate_accept = f.accept;
    s.candidate_evidence = f.evidence;
    rep.best_evidence = f.evidence;
    rep.found = true;
    if (refound && within(s.T_candidate, T_last_candidate, 1.0)) lock(s.T_candidate, f.evidence);
  }
  rep.cancelled = rep.cancelled || stop.stop_requested();
  rep.search_ms = ms_between(t0, Clock::now());
  return rep;
}

void ObjectSearch::take_consensus() {
  if (p_.consensus_candidates < 2) return;
  for (const Refined& a : refined_) {
    if (!a.held || a.found.evidence < p_.consensus_evidence) continue;
    std::uint64_t candidates = 0;  // the detector's candidates one of whose starts ends held near a
    for (const Refined& b : refined_)
      if (b.held && within_confirm_limits(p_, a.found.T_cam_obj, b.found.T_cam_obj, 1.0)) candidates |= std::uint64_t{1} << b.candidate;
    if (std::popcount(candidates) >= p_.consensus_candidates && accepted_.size() < accepted_.capacity())
      accepted_.push_back(a.found);
  }
}

SearchStep search_step(const ObjectSearchParams& p, scene::Scene& scene, std::size_t object, int& lost_streak,
                       LastSeen& last) {
  scene::Object& o = scene.objects()[object];
  if (o.status == scene::TrackStatus::kLost) {
    // Frames lost only by the status's hysteresis do not count: the tracker still measures.
    lost_streak = o.lost_by_image ? lost_streak + 1 : 0;
    if (lost_streak < p.lost_frames || !p.enabled) return SearchStep::kWaiting;
    // The last pose the image supported (reported tracking), else the prediction held while
    // lost (camera frame).
    const geometry::SE3 T_cam_ref = scene.cameras()[0].T_ref_cam.inverse();
    last.T_cam_obj = T_cam_ref * (o.tracked_once ? o.T_ref_obj_tracked : o.T_ref_obj);
    last.velocity = o.tracked_once ? (geometry::adjoint(T_cam_ref) * o.velocity_tracked).eval() : geometry::Vector6d::Zero();
    last.stamp_s = o.tracked_once ? o.stamp_tracked : -1.0;
    last.leak_typical = o.leak_typical;
    scene.start_search(object);
    return SearchStep::kStarted;
  }
  lost_streak = 0;
  return o.status == scene::TrackStatus::kSearching ? SearchStep::kSearch : SearchStep::kIdle;
}

void set_found_pose(scene::Scene& scene, std::size_t object, const geometry::SE3& T_cam_obj, double evidence) {
  scene.set_pose(object, scene.cameras()[0].T_ref_cam * T_cam_obj);
  scene::Object& o = scene.objects()[object];
  o.status = scene::TrackStatus::kTracking;
  o.evidence = o.quality = evidence;
}

std::span<const SearchReport> ObjectSearch::update(scene::Scene& scene, std::span<const CameraImage> images,
                                                   double stamp_s) {
  const auto objs = scene.objects();
  for (std::size_t i = 0; i < reports_.size(); ++i) reports_[i] = SearchReport{};
  if (images.empty() || images[0].grey.empty()) return {reports_.data(), std::min(reports_.size(), objs.size())};
  const CameraImage& img = images[0];
  for (std::size_t i = 0; i < objs.size() && i < slots_.size(); ++i) {
    Slot& s = slots_[i];
    if (!s.active) continue;
    LastSeen last;
    geometry::SE3 T;
    switch (search_step(p_, scene, i, s.lost_streak, last)) {
      case SearchStep::kWaiting: break;
      case SearchStep::kStarted:
        begin_search(i, &last);
        reports_[i].started = true;
        break;
      case SearchStep::kIdle: end_search(i); break;
      case SearchStep::kSearch:
        reports_[i] = search_frame(i, img, stamp_s, T);
        if (reports_[i].locked) set_found_pose(scene, i, T, reports_[i].best_evidence);
        break;
    }
  }
  return {reports_.data(), std::min(reports_.size(), objs.size())};
}

}  // namespace v4r::pipeline
