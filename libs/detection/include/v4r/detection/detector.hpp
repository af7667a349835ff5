// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "v4r/detection/colour_regions.hpp"
#include "v4r/detection/detector_params.hpp"
#include "v4r/detection/edge_alignment.hpp"
#include "v4r/detection/gradient_pyramid.hpp"
#include "v4r/detection/grazing_faces.hpp"
#include "v4r/detection/template_set.hpp"
#include "v4r/geometry/camera.hpp"
#include "v4r/geometry/se3.hpp"
#include "v4r/image/colour_view.hpp"
#include "v4r/image/image_view.hpp"
#include "v4r/model/model.hpp"

namespace v4r::detection {

/// \brief A pose hypothesis of the detector, refined and verified against the image.
struct Hypothesis {
  geometry::SE3 T_cam_obj;      ///< refined pose
  geometry::SE3 T_template;     ///< the template's pose before refinement
  double template_score = 0.0;  ///< fine template match, share of the best possible (0..1)
  Verification verification;    ///< edge test (and, below its bar, colour test) of the refined pose
  /// verification.score >= detect.verify.accept_score, or (colour images) >= leak_score with a
  /// leak <= max_leak; with enough samples either way; or, with no other verified, the best pose
  /// standing out (detect.verify.stand_out_*; a distinct rival whose outline leaks
  /// stand_out_leak_margin more does not count)
  bool verified = false;
  /// Verified, then withdrawn: another verified pose, distinct beyond the model's symmetries,
  /// scores within detect.verify.colour_ambiguity of it (a colour verdict) or edge_ambiguity (an
  /// edge verdict)
  bool ambiguous = false;
  std::uint32_t view = 0;       ///< template view it came from
};

/// \brief What one detect() call did.
struct DetectionResult {
  enum class Status { kOk, kBadImage };
  Status status = Status::kOk;
  int hypotheses = 0;         ///< written to `out`, verified first, then by score; distinct (1 cm / 2 degrees apart)
  int verified = 0;           ///< of which verified
  int coarse_candidates = 0;  ///< coarse matches taken to the fine level
  /// Regions of the model's colour the search was restricted to; -1: no colour stage (the model
  /// has no face colour, a grey image, or detect.colour.enabled off). 0: nothing searched.
  int colour_regions = -1;
  double colour_ms = 0.0, gradient_ms = 0.0, search_ms = 0.0, refine_ms = 0.0, total_ms = 0.0;
};

/// \brief Finds a CAD-modelled object in an image without a prior pose (issue 10).
///
/// Per frame: gradients (colour: the channel of largest magnitude) at full, 1/2 and 1/4
/// resolution; quantised orientations spread and turned into response maps; every coarse
/// template scored at every second pixel of the 1/4 level; the best coarse candidates' child
/// templates scored around them at 1/2 resolution; the best distinct hypotheses turned into poses
/// (template view moved to the matched pixel), refined by a 6-DoF edge alignment and verified by
/// the edge test (share of the projected model's edge samples with a matching gradient).
///
/// When the model's faces carry a colour (dominant_face_colour) and detect.colour.enabled, a
/// colour image is first searched for regions of that colour at 1/4 resolution
/// (ColourRegions); coarse templates are then scored only where their coloured footprint holds a
/// region of matching area, and an image without such a region gives no hypothesis at once
/// (before its gradients are computed).
///
/// Use in the vision cycle:
/// \code
///   Detector det(model, templates, camera, params);           // set-up: allocates
///   std::array<Hypothesis, 10> hyp;
///   DetectionResult r = det.detect(colour_view, hyp);          // per frame: allocates nothing
///   if (r.verified > 0) start_tracking(hyp[0].T_cam_obj);      // hyp sorted, verified first
///   // later, e.g. to confirm a pose on a new frame:
///   det.set_image(colour_view); Verification v = det.verify(T); det.refine(T);
/// \endcode
/// detect(), set_image(), verify() and refine() allocate nothing and throw nothing; an image
/// whose size differs from the camera's gives Status::kBadImage. Not thread-safe (one Detector
/// per thread; the TemplateSet may be shared).
class Detector {
 public:
  /// `cam` must give the image size (width, height) of the frames; `templates` must be built for
  /// its focal lengths (build_templates or load_or_build with the same camera and `p`).
  Detector(std::shared_ptr<const model::Model> model, std::shared_ptr<const TemplateSet> templates,
           const geometry::PinholeCamera& cam, const DetectorParams& p);

  /// Searches the whole image (or its colour regions); writes up to out.size() hypotheses (at most
  /// detect.search.max_hypotheses), sorted by verification score (verified ones first).
  DetectionResult detect(const image::ColourView& bgr, std::span<Hypothesis> out);
  DetectionResult detect(const image::ImageView& grey, std::span<Hypothesis> out);

  /// Computes the gradients of a frame for verify() and refine() without searching.
  bool set_image(const image::ColourView& bgr);
  bool set_image(const image::ImageView& grey);
  /// The edge test of a pose on the last image given to detect() or set_image().
  Verification verify(const geometry::SE3& T_cam_obj);
  /// 6-DoF edge alignment of a pose on the last image; returns the iterations that moved it.
  int refine(geometry::SE3& T_cam_obj);
  /// The final alignment of a pose already on the object's edges (detect() applies it to the best
  /// verified pose): all edge samples, edges placed to a fraction of a pixel
  /// (detect.verify.polish_*); returns the iterations that moved it.
  int polish(geometry::SE3& T_cam_obj);
  /// The twin test (detect.verify.twin_margin) of a pose on the last image: when it places one of
  /// the model's near-symmetric twins of the pose (a turn that maps the model onto itself but for
  /// a few edges) better, the pose moves to that twin. Returns whether it moved.
  bool prefer_twin(geometry::SE3& T_cam_obj);
  /// Whether the model has near-symmetric twins (detect.verify.near_symmetry).
  [[nodiscard]] bool has_twins() const { return !near_symmetries_.empty(); }

  [[nodiscard]] const DetectorParams& params() const { return p_; }
  /// The gradients of the last image (for display and diagnosis).
  [[nodiscard]] const GradientPyramid& gradients() const { return pyramid_; }
  [[nodiscard]] const TemplateSet& templates() const { return *templates_; }
  /// \brief A search candidate of the last detect() (for diagnosis): template view, score (x1000
  /// of the best possible at its level) and anchor (1/2-resolution pixels).
  struct CandidateInfo {
    std::uint32_t view = 0;
    int score = 0;
    int x = 0, y = 0;
  };
  /// The last detect()'s coarse candidates (ranked by their probe at 1/2 resolution) or its
  /// picked hypotheses before refinement (`picked`), for diagnosis.
  [[nodiscard]] std::size_t candidate_count(bool picked) const { return picked ? picked_.size() : coarse_.size(); }
  [[nodiscard]] CandidateInfo candidate(bool picked, std::size_t i) const;
  /// The colour stage, or nullptr when the model has no face colour or it is disabled.
  [[nodiscard]] const ColourRegions* colour_regions() const { return colour_.get(); }

 private:
  struct Candidate {
    int score = 0;
    std::uint32_t index = 0;  // coarse template index (coarse stage) or view (fine stage)
    std::int16_t x = 0, y = 0;
  };
  DetectionResult run(std::span<Hypothesis> out);
  /// With no hypothesis verified, verifies the best-scoring one that stands out
  /// (detect.verify.stand_out_*): distinct poses whose outline leaks stand_out_leak_margin more
  /// than its own are no rivals, so a pose below such a one may stand out.
  void verify_stand_out();
  /// Replaces the best-scoring hypothesis, and the best verified one, by its near-symmetric twin
  /// when the twin's distinctive edge samples match better (detect.verify.twin_margin).
  void resolve_twins();
  /// h moves to its near-symmetric twin when the twin matches better where they differ (twin_margin).
  void prefer_twin(Hypothesis& h);
  /// After the ranking: ranks first a distinct verified pose that scores within
  /// detect.verify.tie_score of the best one and whose distinctive edge samples match by
  /// tie_margin more (a near tie decided where the two poses differ).
  void break_near_tie();
  /// After the ranking: the best verified pose gives way to a distinct pose around it (its samples
  /// within the other's box, covering at most 0.8 of it) that stands out in colour (leaks at most
  /// stand_out_max_leak, and no more than it), scores stand_out_score and matches
  /// detect.verify.enclosing_factor times as many edge samples in runs: a far pose nested in the
  /// object's image, on one of its faces' outline.
  void give_way_to_enclosing();
  /// After the ranking: of the verified poses near the best one and scoring about as well
  /// (detect.verify.consensus_*), three or more, the medoid is ranked first.
  void take_consensus();
  /// Hypotheses refined and verified first (detect.search.max_hypotheses, or detect.colour's).
  std::size_t first_batch() const;
  /// Whether a is b turned by one of the model's near symmetries (within distinct_m / distinct_deg).
  bool is_twin(const geometry::SE3& a, const geometry::SE3& b) const;
  /// Polishes the best verified hypothesis (EdgeAligner::polish, detect.verify.polish_*), kept
  /// unless its edge score drops by more than a little.
  void polish_best();
  /// Turns the best verified pose so that a large face it sees edge-on is seen
  /// (GrazingFaces, detect.verify.unfold_*), polishes it and keeps it when its edge score rises.
  void unfold_best();
  /// Moves `h` to pose T whose edge test is `v`; a leak measured at the old pose is measured again.
  void move_hypothesis(Hypothesis& h, const geometry::SE3& T, const Verification& v);
  /// Poses farther apart than detect.verify.distinct_m or distinct_deg, modulo the symmetries.
  [[nodiscard]] bool distinct(const geometry::SE3& a, const geometry::SE3& b) const;
  /// +1: T's distinctive edge samples match by twin_margin more than those of its twin under S
  /// (refined into `twin`); -1: the twin's do; 0: neither, or too few distinctive samples.
  int twin_verdict(const geometry::SE3& T, const geometry::SE3& S, geometry::SE3& twin);
  /// Full-resolution box of the coarse templates placed over the colour regions (their anchor
  /// windows plus their extent grown by 15 %), grown by detect.colour.roi_margin.
  PixelBox colour_roi() const;
  void coarse_search();
  /// Scores coarse template k at the anchors (2i, 2j), i in [ilo, ihi], j in [jlo, jhi] (already
  /// inside the level) and keeps its best as a candidate.
  void scan_coarse(std::size_t k, int ilo, int jlo, int ihi, int jhi, int& worst);
  void fine_search();
  /// Best fine score (x1000 of the best possible) of a view around 1/2-resolution pixel (cx, cy)
  /// within detect.search.fine_window, and where; -1 when the template does not fit.
  int score_fine(std::uint32_t view, int cx, int cy, int& bx, int& by) const;

  std::shared_ptr<const model::Model> model_;
  std::shared_ptr<const TemplateSet> templates_;
  geometry::PinholeCamera cam_;
  DetectorParams p_;
  GradientPyramid pyramid_;
  EdgeAligner aligner_;
  std::unique_ptr<ColourRegions> colour_;  // null: no colour stage
  bool use_colour_ = false;                // this frame's search is restricted to colour_'s regions
  image::ColourView frame_colour_;         // the colour frame being searched (detect(bgr) only), for the colour test
  std::vector<Candidate> coarse_;         // top coarse candidates (size <= coarse_candidates)
  std::vector<Candidate> fine_;           // fine candidates
  std::vector<Candidate> picked_;         // distinct fine candidates
  std::vector<Hypothesis> work_;          // refined hypotheses before sorting
  std::vector<geometry::SE3> symmetries_;  // of the model (ambiguity of verified poses; at least the identity)
  std::vector<geometry::SE3> near_symmetries_;  // detect.verify.near_symmetry: twins a pose must stand out from
  ViewRange range_;                        // p.views resolved for the model and camera
  GrazingFaces grazing_;                   // the model's large faces, to unfold (unfold_best)
};

}  // namespace v4r::detection
