// v4r - robust model-based object tracking. MIT licence.
// The detector on rendered images: verified poses within 5 cm / 5 degrees (modulo the model's
// symmetries) from random poses in the view range, no verified pose on object-free images, and
// no heap allocation per frame. The large measurement is bench/detection_eval (numbers in the
// README's detection section); these tests keep ctest short with a few images per condition.
#include <array>
#include <atomic>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <cstdlib>
#include <new>
#include <optional>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "degrees.hpp"
#include "detection_scenes.hpp"
#include "test_templates.hpp"
#include "v4r/detection/detector.hpp"
#include "v4r/detection/edge_alignment.hpp"
#include "v4r/detection/gradient_pyramid.hpp"
#include "v4r/detection/symmetry.hpp"
#include "v4r/io/frame_source.hpp"
#include "v4r/model/cao_reader.hpp"

// Counting global allocator (as in the pipeline's cycle test), shared by the binary's tests.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace alloc_count {
std::atomic<bool> counting{false};
std::atomic<long> allocations{0};
}  // namespace alloc_count
void* operator new(std::size_t n) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

using namespace v4r;
using namespace v4r::detection;

namespace {

struct Fixture {
  std::shared_ptr<const model::Model> model;
  std::shared_ptr<const TemplateSet> templates;
  std::vector<geometry::SE3> symmetries;
  DetectorParams params;
  geometry::PinholeCamera cam = synth::default_camera();
};

/// The view range of a fixture's templates: narrower than the default (quicker to build in a
/// test) over half or all the azimuths, or the default one (bench/detection_eval's).
enum class Views { kHalfAzimuths, kAllAzimuths, kDefault };

Fixture make(std::string (*cao)(), Views views = Views::kHalfAzimuths) {
  Fixture f;
  auto m = model::parse_cao(cao(), "m");
  EXPECT_TRUE(m);
  f.model = std::make_shared<const model::Model>(std::move(*m));
  if (views != Views::kDefault) {
    f.params.views.azimuth_min_deg = 0;
    f.params.views.azimuth_max_deg = views == Views::kAllAzimuths ? 360 : 180;
    f.params.views.inplane_min_deg = -20;
    f.params.views.inplane_max_deg = 20;
  }
  auto ts = test::test_templates(*f.model, f.cam, f.params);
  EXPECT_TRUE(ts) << ts.error().to_string();
  f.templates = *ts;
  f.symmetries = model_symmetries(*f.model);
  return f;
}

/// Successes (verified best pose within 5 cm / 5 degrees) and wrong verified poses over `n`
/// random poses (drawn with `seed`) rendered in scene `s` (render seeds from `render_seed`, by
/// default `seed`).
std::pair<int, int> run(const Fixture& f, scenes::Scene s, int n, unsigned seed, std::optional<unsigned> render_seed = {}) {
  Detector det(f.model, f.templates, f.cam, f.params);
  std::array<Hypothesis, 16> hyp;
  std::mt19937 rng(seed);
  int ok = 0, wrong = 0;
  for (int k = 0; k < n; ++k) {
    const geometry::SE3 T = scenes::random_pose(*f.model, f.params.views, f.cam, rng);
    const cv::Mat img = scenes::render_scene(*f.model, T, f.cam, s, render_seed.value_or(seed) + static_cast<unsigned>(k));
    const DetectionResult r = det.detect(io::as_colour_view(img), hyp);
    EXPECT_EQ(r.status, DetectionResult::Status::kOk);
    if (r.verified == 0) continue;
    const PoseError e = symmetric_pose_error(hyp[0].T_cam_obj, T, f.symmetries);
    if (e.translation <= 0.05 && e.rotation <= 5 * kDeg) ++ok;
    else ++wrong;
  }
  return {ok, wrong};
}

/// run() summed over scenes, `n` renders each, the seed advancing by 100 from scene to scene.
std::pair<int, int> run_scenes(const Fixture& f, std::initializer_list<scenes::Scene> ss, int n, unsigned seed) {
  int ok = 0, wrong = 0;
  for (const scenes::Scene s : ss) {
    const auto [o, w] = run(f, s, n, seed);
    seed += 100;
    ok += o;
    wrong += w;
  }
  return {ok, wrong};
}

}  // namespace

TEST(Symmetry, BoxHasFourFlangeFourPlainRotations) {
  const auto box = std::move(*model::parse_cao(synth::box_cao(), "b"));
  EXPECT_EQ(model_symmetries(box).size(), 4u);  // identity and 180 degrees about x, y, z
  const auto flange = std::move(*model::parse_cao(synth::flange_cao(), "f"));
  EXPECT_EQ(model_symmetries(flange).size(), 4u);  // 0, 90, 180, 270 degrees about z
  const auto ship = std::move(*model::parse_cao(synth::ship_mockup_cao(), "s"));
  const auto s = model_symmetries(ship);
  ASSERT_GE(s.size(), 1u);
  EXPECT_TRUE(s[0].translation().norm() < 1e-12 || s.size() > 1);
}

// A flange as CAD exports write it (the independent benchmark's): faces only, and a circle placed
// by two points on its rim. Those two points are not features: the model keeps its four turns.
TEST(Symmetry, CirclesRimPointsDoNotBreakTheSymmetryAndTheNearestTurnIsChosen) {
  const std::string cao =
      "V1\n12\n-0.05 -0.05 0\n-0.05 0.05 0\n0.05 0.05 0\n0.05 -0.05 0\n-0.05 -0.05 0.02\n"
      "0.05 -0.05 0.02\n0.05 0.05 0.02\n-0.05 0.05 0.02\n0 0 0.02\n0 0 0.05\n0.03 0 0.05\n0 0.03 0.05\n"
      "0\n0\n6\n4 0 1 2 3\n4 4 5 6 7\n4 0 3 5 4\n4 2 1 7 6\n4 1 0 4 7\n4 3 2 6 5\n"
      "1\n8 9 0.03\n1\n0.03 9 10 11\n";
  const auto flange = std::move(*model::parse_cao(cao, "f"));
  const auto sym = model_symmetries(flange);
  ASSERT_EQ(sym.size(), 4u);
  // A pose found a quarter turn from the one last seen is reported as the last one's equivalent.
  const geometry::SE3 last(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 0).normalized())),
                           Eigen::Vector3d(0.05, -0.02, 0.5));
  const geometry::SE3 turned = last * geometry::SE3(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())),
                                                    Eigen::Vector3d::Zero());
  const geometry::SE3 moved = geometry::SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY())),
                                            Eigen::Vector3d(0.01, 0, 0)) * turned;
  const geometry::SE3 n = nearest_symmetric(moved, last, sym);
  EXPECT_LT(geometry::rotation_angle_between(n, last), 0.06);
  EXPECT_GT(geometry::rotation_angle_between(moved, last), 1.5);
  // The equivalent is the same object in the image: its pose differs by a symmetry only.
  EXPECT_LT(symmetric_pose_error(n, moved, sym).rotation, 1e-9);
  // A box (no quarter turns) is left as it is by a quarter turn.
  const auto box = std::move(*model::parse_cao(synth::box_cao(), "b"));
  const geometry::SE3 nb = nearest_symmetric(moved, last, model_symmetries(box));
  EXPECT_LT(geometry::rotation_angle_between(nb, moved), 1e-9);
}

TEST(Symmetry, TheSectionTurnedAboutItsVerticalAxisIsANearSymmetry) {
  // Its walls are 12 and 10 cm high: turned half about z, every edge lands within 2 cm of an
  // edge (5 % of its 0.52 m diagonal is 2.6 cm), but it is no symmetry.
  const auto section = std::move(*model::parse_cao(synth::ship_section_cao(), "s"));
  ASSERT_EQ(model_symmetries(section).size(), 1u);
  const auto near = near_symmetries(section, 0.05);
  ASSERT_EQ(near.size(), 1u);
  EXPECT_NEAR(geometry::rotation_angle_between(near[0], geometry::SE3()), M_PI, 1e-9);
  EXPECT_NEAR(std::abs(near[0].rotation()(2, 2)), 1.0, 1e-9);  // about z
  EXPECT_TRUE(near_symmetries(section, 0.02).empty());
  EXPECT_TRUE(near_symmetries(section, 0.0).empty());
  // The box's exact symmetries are not near ones, and its quarter turns move edges by 2.5 cm or
  // more (9 % of its diagonal).
  const auto box = std::move(*model::parse_cao(synth::box_cao(), "b"));
  EXPECT_TRUE(near_symmetries(box, 0.05).empty());
}

TEST(Detector, ASectionAndItsNearSymmetricTwinAreToldApartWhereTheyDiffer) {
  // The section and its twin (turned half about z: walls of 12 and 10 cm swapped) score close
  // over all their edge samples; on the samples where they differ (the walls' tops), the truth
  // matches and the twin does not (EdgeAligner::compare_twins). Plain and motion-blurred images.
  const auto section = std::make_shared<const model::Model>(std::move(*model::parse_cao(synth::ship_section_cao(), "s")));
  const auto near = near_symmetries(*section, 0.05);
  ASSERT_EQ(near.size(), 1u);
  DetectorParams p;
  const geometry::PinholeCamera cam = synth::default_camera();
  EdgeAligner aligner(*section, cam, p);
  GradientPyramid g(cam.width, cam.height, p.search.fine_spread, p.search.coarse_spread);
  const GradientThreshold thr{p.verify.min_gradient, p.verify.min_gradient_floor, p.verify.noise_factor};
  std::mt19937 rng(77);
  int told = 0, wrong_way = 0;
  double overall_gap = 0.0, distinct_gap = 0.0;
  const int n = 10;
  for (int k = 0; k < n; ++k) {
    const geometry::SE3 T = scenes::random_pose(*section, p.views, cam, rng);
    const cv::Mat img = scenes::render_scene(*section, T, cam, k % 2 ? scenes::Scene::kBlur : scenes::Scene::kPlain,
                                             500u + static_cast<unsigned>(k));
    ASSERT_TRUE(g.compute(io::as_colour_view(img), thr));
    geometry::SE3 Tr = T, twin = T * near[0];  // (both refined, as the detector's hypotheses are)
    aligner.refine(g, Tr);
    aligner.refine(g, twin);
    const double truth_score = aligner.verify(g, Tr).score, twin_score = aligner.verify(g, twin).score;
    overall_gap += truth_score - twin_score;
    const EdgeAligner::TwinShares t = aligner.compare_twins(g, Tr, twin, 2.0 * p.verify.match_distance_px);
    told += t.na >= 8 && t.nb >= 8 && t.a >= t.b + p.verify.twin_margin ? 1 : 0;
    wrong_way += t.b >= t.a + p.verify.twin_margin ? 1 : 0;
    distinct_gap += t.a - t.b;
  }
  // Measured (truth and twin both refined): the twin scores 0.07..0.26 below the truth over all
  // samples (mean 0.14), 0.02..0.72 below it on the distinctive ones (mean 0.35); told apart by
  // twin_margin (0.15) in 8 of 10, the other way in none. Since blurred edges are matched at
  // their centroids (detect.verify.plateau): mean gaps 0.13 and 0.36, told apart in 7 of 10 (one
  // more blurred image; one blurred and one plain image fewer, gaps 0.10 and 0.14 where they were
  // 0.17).
  std::printf("mean gap %.2f over all samples, %.2f on the distinctive ones; told apart in %d of %d, the other way in %d\n",
              overall_gap / n, distinct_gap / n, told, n, wrong_way);
  EXPECT_GT(distinct_gap, 2.0 * overall_gap);
  EXPECT_GE(told, 7) << "of " << n;
  EXPECT_EQ(wrong_way, 0);
}

TEST(Detector, OnBlurredImagesASectionAndItsTwinAreToldByTheirEdgesCentres) {
  // Motion-blurred renders of the section. Where the share test leaves the truth and its twin
  // undecided (both poses' distinctive samples find a gradient on the smeared edges), the truth's
  // distinctive samples lie nearer the centres of the image's edges
  // (EdgeAligner::TwinShares::residual_*, by detect.verify.twin_residual_margin). Measured: 7 of
  // these 40 undecided; of them 6 told, 1 the other way.
  const auto section = std::make_shared<const model::Model>(std::move(*model::parse_cao(synth::ship_section_cao(), "s")));
  const auto near = near_symmetries(*section, 0.05);
  ASSERT_EQ(near.size(), 1u);
  DetectorParams p;
  ASSERT_GT(p.verify.twin_residual_margin, 0.0);
  const geometry::PinholeCamera cam = synth::default_camera();
  EdgeAligner aligner(*section, cam, p);
  GradientPyramid g(cam.width, cam.height, p.search.fine_spread, p.search.coarse_spread);
  const GradientThreshold thr{p.verify.min_gradient, p.verify.min_gradient_floor, p.verify.noise_factor};
  std::mt19937 rng(91);
  int undecided = 0, told = 0, wrong_way = 0;
  const int n = 40;
  for (int k = 0; k < n; ++k) {
    const geometry::SE3 T = scenes::random_pose(*section, p.views, cam, rng);
    const cv::Mat img = scenes::render_scene(*section, T, cam, scenes::Scene::kBlur, 900u + static_cast<unsigned>(k));
    ASSERT_TRUE(g.compute(io::as_colour_view(img), thr));
    geometry::SE3 Tr = T, twin = T * near[0];
    aligner.refine(g, Tr);
    aligner.refine(g, twin);
    const EdgeAligner::TwinShares t = aligner.compare_twins(g, Tr, twin, 2.0 * p.verify.match_distance_px, true);
    if (t.na < 8 || t.nb < 8 || std::abs(t.a - t.b) >= p.verify.twin_margin) continue;
    ++undecided;
    told += t.residual_a + p.verify.twin_residual_margin <= t.residual_b ? 1 : 0;
    wrong_way += t.residual_b + p.verify.twin_residual_margin <= t.residual_a ? 1 : 0;
  }
  std::printf("%d of %d blurred images undecided by the shares; by the edges' centres %d told, %d the other way\n", undecided, n,
              told, wrong_way);
  EXPECT_GE(undecided, 3);  // (the case this test is about)
  EXPECT_GE(4 * told, 3 * undecided);
  EXPECT_LE(wrong_way, 1);
}

TEST(Detector, FindsTheBoxOnPlainTexturedAndNoisyImages) {
  const Fixture f = make(synth::box_cao);
  int ok = 0, wrong = 0, n = 0;
  for (const auto s : {scenes::Scene::kPlain, scenes::Scene::kTextured, scenes::Scene::kNoise}) {
    const auto [o, w] = run(f, s, 6, 11u + static_cast<unsigned>(n));
    ok += o;
    wrong += w;
    n += 6;
  }
  // Measured (bench/detection_eval, 40 images each): plain 92 %, textured 80 %, noise 70 %. Here 14
  // of 18, 3 wrong (main, with its fixed verification threshold: 14, 2 wrong; the threshold that
  // follows the frame's noise lets one more wrong pose through and finds blurred objects).
  EXPECT_GE(ok, 14) << "of " << n;
  EXPECT_LE(wrong, 3);
}

TEST(Detector, FindsTheFlangeInClutter) {
  const Fixture f = make(synth::flange_cao);
  const auto [ok, wrong] = run(f, scenes::Scene::kClutter, 6, 5u);
  EXPECT_GE(ok, 5);
  EXPECT_EQ(wrong, 0);
}

TEST(Detector, NoVerifiedPoseOnImagesWithoutTheObject) {
  const Fixture f = make(synth::box_cao);
  Detector det(f.model, f.templates, f.cam, f.params);
  std::array<Hypothesis, 16> hyp;
  std::mt19937 rng(99);
  const std::string visp = "/usr/share/visp-images-data/ViSP-images/";
  const std::array<std::string, 3> photos{"", visp + "Klimt/Klimt.png", visp + "Solvay/Solvay_conference_1927_Version2_1024x705.png"};
  int images = 0;
  for (int k = 0; k < 9; ++k) {
    const cv::Mat img = scenes::empty_scene(f.cam, k % 3, photos[static_cast<std::size_t>(k % 3)], rng);
    if (img.empty()) continue;  // visp-images-data not installed (make test installs it)
    const DetectionResult r = det.detect(io::as_colour_view(img), hyp);
    ++images;
    EXPECT_EQ(r.verified, 0) << "image " << k << ": score " << hyp[0].verification.score;
  }
  EXPECT_GE(images, 3);
}

TEST(Detector, AllocatesNothingPerFrameAndRejectsAWrongImageSize) {
  const Fixture f = make(synth::box_cao);
  Detector det(f.model, f.templates, f.cam, f.params);
  std::array<Hypothesis, 16> hyp;
  std::mt19937 rng(3);
  const geometry::SE3 T = scenes::random_pose(*f.model, f.params.views, f.cam, rng);
  const cv::Mat img = scenes::render_scene(*f.model, T, f.cam, scenes::Scene::kTextured, 1);
  cv::Mat grey;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  det.detect(io::as_colour_view(img), hyp);  // warm-up
  g_allocations = 0;
  g_counting = true;
  const DetectionResult r1 = det.detect(io::as_colour_view(img), hyp);
  const DetectionResult r2 = det.detect(io::as_view(grey), hyp);
  geometry::SE3 Tr = T;
  det.refine(Tr);
  const Verification v = det.verify(Tr);
  g_counting = false;
  EXPECT_EQ(g_allocations.load(), 0);
  EXPECT_GT(r1.hypotheses, 0);
  EXPECT_GT(r2.hypotheses, 0);
  EXPECT_GT(v.score, 0.8);  // the truth refined on its own image

  const cv::Mat small(100, 100, CV_8UC3, cv::Scalar::all(0));
  EXPECT_EQ(det.detect(io::as_colour_view(small), hyp).status, DetectionResult::Status::kBadImage);
  EXPECT_EQ(det.detect(image::ColourView{}, hyp).status, DetectionResult::Status::kBadImage);
}

TEST(Detector, TheTemplateSearchKeepsTheBestSumsAtTheirFirstBestAnchors) {
  // The search sums responses in tiles of adjacent anchors from maps split by pixel phase; here
  // every coarse template is summed at every anchor straight from the response maps. The coarse
  // candidates must be the templates of the highest shares, each at the first anchor (row order)
  // of its best sum; each picked fine candidate's score must be the sum at its anchor.
  const Fixture f = make(synth::box_cao);
  const TemplateSet& ts = *f.templates;
  const SearchParams& sp = f.params.search;
  Detector det(f.model, f.templates, f.cam, f.params);
  std::array<Hypothesis, 16> hyp;
  std::mt19937 rng(21);
  std::vector<std::size_t> template_of_view(ts.views.size(), ts.coarse.templates.size());
  for (std::size_t k = 0; k < ts.coarse_views.size(); ++k) template_of_view[ts.coarse_views[k]] = k;
  const auto sum_at = [](const OrientationLevel& L, const TemplateLevel& level, const Template& t, int x, int y) {
    int sum = 0;
    for (std::uint32_t q = t.first; q < t.first + t.count; ++q) {
      const Feature& ft = level.features[q];
      sum += L.response[ft.orientation][static_cast<std::size_t>(y + ft.y) * L.width + (x + ft.x)];
    }
    return sum;
  };
  const auto share = [](int sum, const Template& t) { return static_cast<int>(1000.0 * sum / (4.0 * t.count)); };
  for (const auto scene : {scenes::Scene::kClutter, scenes::Scene::kTextured}) {
    const geometry::SE3 T = scenes::random_pose(*f.model, f.params.views, f.cam, rng);
    const cv::Mat img = scenes::render_scene(*f.model, T, f.cam, scene, 7);
    det.detect(io::as_colour_view(img), hyp);
    const OrientationLevel& C = det.gradients().coarse();
    // Every coarse template's best sum over the anchors (2i, 2j) that keep it inside the level.
    struct Best {
      int sum = -1, x = 0, y = 0;
    };
    std::vector<Best> best(ts.coarse.templates.size());
    std::vector<std::size_t> eligible;
    for (std::size_t k = 0; k < ts.coarse.templates.size(); ++k) {
      const Template& t = ts.coarse.templates[k];
      if (t.count < 4) continue;
      for (int y = 0; y + t.y1 <= C.height - 1; y += 2) {
        if (y + t.y0 < 0) continue;
        for (int x = 0; x + t.x1 <= C.width - 1; x += 2)
          if (x + t.x0 >= 0)
            if (const int s = sum_at(C, ts.coarse, t, x, y); s > best[k].sum) best[k] = {s, x, y};
      }
      if (best[k].sum >= std::ceil(sp.coarse_min_score * 4.0 * t.count)) eligible.push_back(k);
    }
    const std::size_t n = det.candidate_count(false);
    ASSERT_EQ(n, std::min(eligible.size(), static_cast<std::size_t>(sp.coarse_candidates)));
    std::vector<bool> kept(ts.coarse.templates.size(), false);
    int lowest = 1000;
    for (std::size_t i = 0; i < n; ++i) {
      const Detector::CandidateInfo c = det.candidate(false, i);
      const std::size_t k = template_of_view[c.view];
      ASSERT_LT(k, ts.coarse.templates.size());
      kept[k] = true;
      EXPECT_EQ(c.x, 2 * best[k].x) << "template " << k;  // candidates give 1/2-resolution pixels
      EXPECT_EQ(c.y, 2 * best[k].y) << "template " << k;
      lowest = std::min(lowest, share(best[k].sum, ts.coarse.templates[k]));
    }
    for (const std::size_t k : eligible) {
      if (kept[k]) continue;
      EXPECT_LE(share(best[k].sum, ts.coarse.templates[k]), lowest) << "template " << k << " left out";
    }
    const OrientationLevel& F = det.gradients().fine();
    ASSERT_GT(det.candidate_count(true), 0U);
    for (std::size_t i = 0; i < det.candidate_count(true); ++i) {
      const Detector::CandidateInfo c = det.candidate(true, i);
      const Template& t = ts.fine.templates[c.view];
      EXPECT_EQ(c.score, share(sum_at(F, ts.fine, t, c.x, c.y), t)) << "picked " << i;
    }
  }
}

TEST(Detector, VerifiesTheTruthOnMotionBlurredImages) {
  // Motion blur (bench/detection_eval's blur scene: ~10 px of motion over the exposure) spreads an
  // edge's step over several pixels; under a fixed threshold of 8 grey/px most of the box's edges
  // matched nothing and the truth, refined on its own image, scored 0.44..0.80 (2 of 12 above
  // accept_score 0.75). The verification's threshold follows the frame's noise instead.
  const Fixture f = make(synth::box_cao);
  Detector det(f.model, f.templates, f.cam, f.params);
  std::mt19937 rng(1000u + 4u * 77u);
  int verified = 0;
  const int n = 8;
  for (int k = 0; k < n; ++k) {
    const geometry::SE3 T = scenes::random_pose(*f.model, f.params.views, f.cam, rng);
    const cv::Mat img = scenes::render_scene(*f.model, T, f.cam, scenes::Scene::kBlur, 100u + static_cast<unsigned>(k));
    ASSERT_TRUE(det.set_image(io::as_colour_view(img)));
    geometry::SE3 Tr = T;
    det.refine(Tr);
    const Verification v = det.verify(Tr);
    const PoseError e = symmetric_pose_error(Tr, T, f.symmetries);
    if (v.score >= f.params.verify.accept_score && e.translation <= 0.05 && e.rotation <= 5 * kDeg) ++verified;
  }
  EXPECT_GE(verified, 7) << "of " << n;
}

TEST(Detector, EdgeTestSumsGradientsAlongTheEdgeOnNoisyImages) {
  // Noise turns a weak edge's gradient by more than the 15 degrees a match allows, so runs of
  // matches break and the truth scores below accept_score. Summed over 1 px either side along
  // the edge (detect.verify.tangent_support) the gradient's noise falls by sqrt(3), not its edge.
  const Fixture f = make(synth::ship_section_cao);
  DetectorParams one = f.params;
  one.verify.tangent_support = 0;
  Detector det(f.model, f.templates, f.cam, f.params), det_one(f.model, f.templates, f.cam, one);
  std::mt19937 rng(1000u + 3u * 77u);
  const int n = 16;
  double sum = 0.0, sum_one = 0.0;
  int verified = 0, verified_one = 0;
  for (int k = 0; k < n; ++k) {
    const geometry::SE3 T = scenes::random_pose(*f.model, f.params.views, f.cam, rng);
    const cv::Mat img = scenes::render_scene(*f.model, T, f.cam, scenes::Scene::kNoise, 100u + static_cast<unsigned>(k));
    ASSERT_TRUE(det.set_image(io::as_colour_view(img)));
    ASSERT_TRUE(det_one.set_image(io::as_colour_view(img)));
    // Each scores the truth refined on the image by its own edge alignment, as detect() would.
    geometry::SE3 Tr = T, Tr_one = T;
    det.refine(Tr);
    det_one.refine(Tr_one);
    const Verification v = det.verify(Tr), v_one = det_one.verify(Tr_one);
    sum += v.score;
    sum_one += v_one.score;
    verified += v.score >= f.params.verify.accept_score ? 1 : 0;
    verified_one += v_one.score >= f.params.verify.accept_score ? 1 : 0;
    // A pose 15 % farther (nested in the object's image) does not gain a verdict.
    geometry::SE3 Tn = T;
    Tn.set_translation(1.15 * T.translation());
    EXPECT_LT(det.verify(Tn).score, f.params.verify.leak_score) << "image " << k;
  }
  std::printf("truth's edge score on noisy images: %.2f summed along the edge, %.2f one pixel; verified %d vs %d of %d\n",
              sum / n, sum_one / n, verified, verified_one, n);
  // Measured: mean 0.78 vs 0.72, verified 12 vs 6 of 16.
  EXPECT_GT(sum / n, sum_one / n + 0.03);
  EXPECT_GE(verified, verified_one + 3);
}

TEST(Detector, NoisyFramesKeepTheFullGradientThreshold) {
  // The relative threshold: the floor on a clean frame, the ceiling (min_gradient) on a noisy one.
  const Fixture f = make(synth::box_cao);
  Detector det(f.model, f.templates, f.cam, f.params);
  cv::Mat clean(f.cam.height, f.cam.width, CV_8UC3, cv::Scalar::all(120));
  ASSERT_TRUE(det.set_image(io::as_colour_view(clean)));
  EXPECT_NEAR(det.gradients().noise(), 0.0, 1e-9);
  cv::Mat noise(clean.size(), CV_16SC3), noisy;
  cv::randn(noise, cv::Scalar::all(0), cv::Scalar::all(8));
  cv::add(clean, noise, noisy, cv::noArray(), CV_8UC3);
  ASSERT_TRUE(det.set_image(io::as_colour_view(noisy)));
  const GradientThreshold t{f.params.verify.min_gradient, f.params.verify.min_gradient_floor, f.params.verify.noise_factor};
  EXPECT_GT(det.gradients().noise(), 4.0);  // sigma 8: Sobel |gx|+|gy| per pixel ~ 8 * 0.43 * 2 * 0.8
  EXPECT_DOUBLE_EQ(t.at(det.gradients().noise()), f.params.verify.min_gradient);
  EXPECT_DOUBLE_EQ(t.at(0.0), f.params.verify.min_gradient_floor);
}

TEST(Detector, ColourTestTellsTheOutlineFromANestedPose) {
  // The flange's silhouette, a third of it hidden, leaks fewer of its colours than the same view
  // 25 % farther (nested in the flange's image), which leaks most samples.
  const Fixture f = make(synth::flange_cao);
  EdgeAligner aligner(*f.model, f.cam, f.params);
  std::mt19937 rng(17);
  int low = 0;
  const int n = 8;
  for (int k = 0; k < n; ++k) {
    const geometry::SE3 T = scenes::random_pose(*f.model, f.params.views, f.cam, rng);
    const cv::Mat img = scenes::render_scene(*f.model, T, f.cam, scenes::Scene::kOcclusion, 7u + static_cast<unsigned>(k));
    Verification truth, nested;
    aligner.measure_leak(io::as_colour_view(img), T, truth);
    geometry::SE3 Tn = T;
    Tn.set_translation(1.25 * T.translation());
    aligner.measure_leak(io::as_colour_view(img), Tn, nested);
    EXPECT_GT(truth.leak_samples, 60) << "image " << k;
    // The nested pose never passes; where the truth passes, far apart.
    EXPECT_GT(nested.leak, f.params.verify.max_leak) << "image " << k;
    if (truth.leak <= f.params.verify.max_leak) {
      ++low;
      EXPECT_GT(nested.leak, truth.leak + 0.4) << "image " << k;
    }
  }
  // Measured: 4 of 8 at 0.09..0.18 (nested 0.63..0.99); the others 0.42..0.68 (the occluder's colours).
  EXPECT_GE(low, n / 2);
}

TEST(Detector, FindsTheFlangeWithAThirdOfItHidden) {
  // 30 % of the flange behind the renderer's occluder: the edge test alone (accept_score 0.75)
  // rejects most true poses; poses scoring leak_score (0.5) or more whose silhouette stands out
  // in colour are verified too.
  Fixture f = make(synth::flange_cao);
  const auto [ok, wrong] = run(f, scenes::Scene::kOcclusion, 10, 31u);
  f.params.verify.leak_score = 1.0;  // the colour test off (and the stand-out verdict, which takes it)
  f.params.verify.stand_out_score = 1.0;
  const auto [ok_edges, wrong_edges] = run(f, scenes::Scene::kOcclusion, 10, 31u);
  // Measured: 9 of 10 (5 before the stand-out verdict), none wrong; the edge test alone: 0 of 10.
  EXPECT_GT(ok, ok_edges);
  EXPECT_GE(ok, 4) << "of 10";
  EXPECT_LE(wrong + wrong_edges, 1);
}

TEST(Detector, FindsTheShipSectionWithAThirdOfItHidden) {
  // The section's plates are thin and many: with 30 % of it hidden, the runs of matches along its
  // edges break at the occluder and the truth scores 0.5-0.6 in the edge test, below the old
  // leak_score of 0.6, so its colour test was never asked. From 0.5 it is. (The stand-out
  // verdict, which also verifies partly hidden poses from 0.55, is off here: the colour test's
  // own gain is measured.)
  Fixture f = make(synth::ship_section_cao);
  f.params.verify.stand_out_score = 1.0;
  constexpr int kImages = 16;
  const auto [ok, wrong] = run(f, scenes::Scene::kOcclusion, kImages, 5u);
  f.params.verify.leak_score = 0.6;
  const auto [ok_old, wrong_old] = run(f, scenes::Scene::kOcclusion, kImages, 5u);
  std::printf("section, 30 %% hidden: %d of %d found (%d wrong) with leak_score 0.5, %d (%d) with 0.6\n", ok, kImages, wrong, ok_old,
              wrong_old);
  // Measured: 9 of 16 (none wrong) against 3 (none wrong); 10 against 4 since
  // detect.verify.stand_out_leak_margin; 8 against 2 with the stand-out verdict off (with it,
  // at stand_out_score 0.55 and stand_out_margin 0.08: 11 against 9).
  EXPECT_GE(ok, ok_old + 3);
  EXPECT_GE(ok, 6) << "of " << kImages;
  EXPECT_LE(wrong, wrong_old + 1);
}

TEST(Detector, APartlyHiddenObjectThatStandsOutIsVerified) {
  // A third of the object hidden, its occluder beside the outline: the edge test scores the truth
  // below accept_score and the colour test sees the occluder leak. Nothing else in the image comes
  // within stand_out_margin of it, and it is verified (detect.verify.stand_out_*).
  int ok = 0, ok_off = 0, wrong = 0, wrong_off = 0;
  for (auto cao : {synth::flange_cao, synth::ship_mockup_cao}) {
    Fixture f = make(cao);
    const auto [o, w] = run(f, scenes::Scene::kOcclusion, 12, 47u);
    f.params.verify.stand_out_score = 1.0;  // off
    const auto [o_off, w_off] = run(f, scenes::Scene::kOcclusion, 12, 47u);
    ok += o;
    wrong += w;
    ok_off += o_off;
    wrong_off += w_off;
  }
  // Measured: 18 of 24 (flange and ship mock-up), 13 without; none wrong either way.
  EXPECT_GT(ok, ok_off);
  EXPECT_GE(ok, 16) << "of 24";
  EXPECT_LE(wrong, wrong_off + 1);
}

TEST(Detector, ARivalWhoseOutlineLeaksDoesNotKeepAPoseFromStandingOut) {
  // A third of the object hidden: the truth scores under accept_score, and a distinct pose fitted
  // to the occluder's or the print's edges scores about as much (or more) while its outline leaks
  // the object's colours. With detect.verify.stand_out_leak_margin such a pose is no rival. The
  // gain is a few images in a hundred, so the test counts over five seeds in a row (1-5).
  constexpr int kImages = 20;
  const double margin = VerifyParams{}.stand_out_leak_margin;  // the default
  ASSERT_LT(margin, 1.0);
  int ok = 0, ok_off = 0, wrong = 0, wrong_off = 0;
  for (auto cao : {synth::box_cao, synth::flange_cao}) {
    Fixture f = make(cao);
    for (unsigned seed = 1; seed <= 5; ++seed) {
      f.params.verify.stand_out_leak_margin = margin;
      const auto [o, w] = run(f, scenes::Scene::kOcclusion, kImages, seed);
      f.params.verify.stand_out_leak_margin = 1.0;  // off
      const auto [o_off, w_off] = run(f, scenes::Scene::kOcclusion, kImages, seed);
      ok += o;
      wrong += w;
      ok_off += o_off;
      wrong_off += w_off;
    }
  }
  std::printf("box and flange, 30 %% hidden: %d of %d found (%d wrong) with the leak margin, %d (%d) without\n", ok,
              10 * kImages, wrong, ok_off, wrong_off);
  // Measured: 179 of 200 (9 wrong) against 175 (9 wrong); 186 (5) against 182 (5) with the
  // continued-edge rule and the rules before it.
  EXPECT_GE(ok, ok_off + 2);
  EXPECT_LE(wrong, wrong_off + 1);
}

TEST(Detector, TheColourTestJudgesEachSilhouetteEdgeByItsOwnFace) {
  // The flange's plate sides are in shadow, darker than its top. Compared with all inside colours
  // at once (detect.verify.leak_group_samples 0), a dark background beside the lit top looks
  // like the object, and true, partly hidden poses leak too much to pass; compared edge by edge
  // with the face inside it, fewer do. A nested pose (the same view 25 % farther) still leaks.
  for (auto cao : {synth::flange_cao, synth::ship_mockup_cao}) {
    Fixture f = make(cao);
    DetectorParams all_params = f.params;
    all_params.verify.leak_group_samples = 0;
    ASSERT_GT(f.params.verify.leak_group_samples, 0);
    EdgeAligner grouped(*f.model, f.cam, f.params), all(*f.model, f.cam, all_params);
    std::mt19937 rng(23);
    int pass_grouped = 0, pass_all = 0;
    double sum_grouped = 0.0, sum_all = 0.0;
    const int n = 12;
    for (int k = 0; k < n; ++k) {
      const geometry::SE3 T = scenes::random_pose(*f.model, f.params.views, f.cam, rng);
      const cv::Mat img = scenes::render_scene(*f.model, T, f.cam, scenes::Scene::kOcclusion, 40u + static_cast<unsigned>(k));
      Verification g, a, nested;
      grouped.measure_leak(io::as_colour_view(img), T, g);
      all.measure_leak(io::as_colour_view(img), T, a);
      geometry::SE3 Tn = T;
      Tn.set_translation(1.25 * T.translation());
      grouped.measure_leak(io::as_colour_view(img), Tn, nested);
      EXPECT_GT(nested.leak, f.params.verify.max_leak) << "image " << k;
      ASSERT_GE(g.leak, 0.0);
      ASSERT_GE(a.leak, 0.0);
      sum_grouped += g.leak;
      sum_all += a.leak;
      pass_grouped += g.leak >= 0.0 && g.leak <= f.params.verify.max_leak ? 1 : 0;
      pass_all += a.leak >= 0.0 && a.leak <= f.params.verify.max_leak ? 1 : 0;
    }
    // Measured: mean leak of the truth 0.25 grouped / 0.42 all (flange), 0.28 / 0.35 (ship);
    // where the whole outline leaked (1.00), 0.47..0.59; passing 8 / 7 and 8 / 8 of 12.
    EXPECT_LT(sum_grouped / n + 0.05, sum_all / n);
    EXPECT_GE(pass_grouped, pass_all);
  }
}

TEST(Detector, TheAlignmentFindsAPartlyHiddenBoxWhereItsEdgesAreSeen) {
  // A third of the box behind the renderer's occluder, the alignment started 3 degrees and 1 cm
  // off its true pose (a template's view step): Huber-weighted, it follows the occluder's edges;
  // with Tukey's biweight in the later iterations (detect.verify.refine_tukey) a match a few
  // pixels off stops pulling.
  Fixture f = make(synth::box_cao);
  DetectorParams huber_params = f.params;
  huber_params.verify.refine_tukey_px = 0.0;
  ASSERT_GT(f.params.verify.refine_tukey_px, 0.0);
  Detector tukey(f.model, f.templates, f.cam, f.params), huber(f.model, f.templates, f.cam, huber_params);
  std::array<Hypothesis, 16> hyp;
  std::mt19937 rng(29);
  int held_tukey = 0, held_huber = 0, starts = 0;
  for (int k = 0; k < 16; ++k) {
    const geometry::SE3 T = scenes::random_pose(*f.model, f.params.views, f.cam, rng);
    const cv::Mat img = scenes::render_scene(*f.model, T, f.cam, scenes::Scene::kOcclusion, 60u + static_cast<unsigned>(k));
    tukey.detect(io::as_colour_view(img), hyp);  // (the image's gradients, for refine)
    huber.detect(io::as_colour_view(img), hyp);
    for (const Eigen::Vector3d& w : {Eigen::Vector3d(3, 0, 0), Eigen::Vector3d(0, -3, 0), Eigen::Vector3d(0, 0, 3)}) {
      const geometry::SE3 start = geometry::SE3::from_rvec(Eigen::Vector3d(0.0, 0.0, 0.01), Eigen::Vector3d::Zero()) * T *
                                    geometry::SE3::from_rvec(Eigen::Vector3d::Zero(), w * kDeg);
      geometry::SE3 Tt = start, Th = start;
      tukey.refine(Tt);
      huber.refine(Th);
      const PoseError et = symmetric_pose_error(Tt, T, f.symmetries), eh = symmetric_pose_error(Th, T, f.symmetries);
      held_tukey += et.translation <= 0.01 && et.rotation <= 2.0 * kDeg ? 1 : 0;
      held_huber += eh.translation <= 0.01 && eh.rotation <= 2.0 * kDeg ? 1 : 0;
      ++starts;
    }
  }
  // Measured: 44 (Tukey) against 42 (Huber) of 48 starts within 1 cm / 2 degrees.
  EXPECT_EQ(starts, 48);
  EXPECT_GT(held_tukey, held_huber);
  EXPECT_GE(held_tukey, 40);
}

TEST(Detector, ThePolishPlacesARefinedPoseCloserToTheTruth) {
  // The refinement matches edges to the pixel over at most refine_samples samples; the polish
  // (detect.verify.polish_*) uses every sample and places each edge to a fraction of a pixel.
  // Starts 1 cm and 3 degrees off the truth, refined, then polished: the polished poses are nearer.
  const Fixture f = make(synth::box_cao);
  Detector det(f.model, f.templates, f.cam, f.params);
  std::mt19937 rng(41);
  std::vector<double> refined_t, refined_r, polished_t, polished_r;
  for (int k = 0; k < 12; ++k) {
    const geometry::SE3 T = scenes::random_pose(*f.model, f.params.views, f.cam, rng);
    const auto scene = k % 2 == 0 ? scenes::Scene::kPlain : scenes::Scene::kNoise;
    const cv::Mat img = scenes::render_scene(*f.model, T, f.cam, scene, 70u + static_cast<unsigned>(k));
    ASSERT_TRUE(det.set_image(io::as_colour_view(img)));
    const geometry::SE3 start = geometry::SE3::from_rvec(Eigen::Vector3d(0.0, 0.0, 0.01), Eigen::Vector3d::Zero()) * T *
                                geometry::SE3::from_rvec(Eigen::Vector3d::Zero(), Eigen::Vector3d(3, -2, 1) * kDeg);
    geometry::SE3 Tr = start;
    det.refine(Tr);
    geometry::SE3 Tp = Tr;
    EXPECT_GT(det.polish(Tp), 0);
    const PoseError er = symmetric_pose_error(Tr, T, f.symmetries), ep = symmetric_pose_error(Tp, T, f.symmetries);
    refined_t.push_back(er.translation);
    refined_r.push_back(er.rotation);
    polished_t.push_back(ep.translation);
    polished_r.push_back(ep.rotation);
  }
  const auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const double rt = median(refined_t), rr = median(refined_r), pt = median(polished_t), pr = median(polished_r);
  std::printf("median refined %.2f mm %.2f deg, polished %.2f mm %.2f deg\n", rt * 1e3, rr / kDeg, pt * 1e3, pr / kDeg);
  // Measured: refined 0.31 mm / 0.20 deg, polished 0.23 mm / 0.08 deg.
  EXPECT_LT(pt, rt);
  EXPECT_LT(pr, 0.7 * rr);
}

TEST(Detector, ANearTieIsDecidedWhereTheTwoPosesDiffer) {
  // Two distinct verified poses scoring within detect.verify.tie_score of each other: the one
  // whose distinctive edge samples match better is ranked first (detect.verify.tie_margin).
  // Counted over box and section renders under blur, noise and occlusion, with and without it: no
  // worse (measured: 62 found, 2 wrong either way here; bench/detection_eval over 1200 renders:
  // 1105 -> 1111 found, 39 -> 33 wrong).
  int ok[2] = {0, 0}, wrong[2] = {0, 0};
  for (std::string (*cao)() : {synth::box_cao, synth::ship_section_cao}) {
    Fixture f = make(cao);
    for (int on = 0; on < 2; ++on) {
      if (on == 0) f.params.verify.tie_score = 0.0;
      else f.params.verify.tie_score = DetectorParams{}.verify.tie_score;
      ASSERT_GT(DetectorParams{}.verify.tie_score, 0.0);
      const auto [o, w] = run_scenes(f, {scenes::Scene::kBlur, scenes::Scene::kNoise, scenes::Scene::kOcclusion}, 12, 300);
      ok[on] += o;
      wrong[on] += w;
    }
  }
  std::printf("without: %d found, %d wrong; with: %d found, %d wrong\n", ok[0], wrong[0], ok[1], wrong[1]);
  EXPECT_GE(ok[1], ok[0]);
  EXPECT_LE(wrong[1], wrong[0]);
}

namespace {

/// Successes and wrong verified poses over 40 blurred renders of the fixture's model, without (index 0) and
/// with (1) a rule that `toggle(params, on)` switches; printed, and the rule must lose nothing
/// and avoid at least one wrong pose.
void expect_fewer_wrong_on_blurred_renders(Fixture& f, void (*toggle)(DetectorParams&, bool)) {
  int ok[2] = {0, 0}, wrong[2] = {0, 0};
  for (int on = 0; on < 2; ++on) {
    toggle(f.params, on == 1);
    const auto [o, w] = run(f, scenes::Scene::kBlur, 40, 700);
    ok[on] = o;
    wrong[on] = w;
  }
  std::printf("without: %d found, %d wrong; with: %d found, %d wrong\n", ok[0], wrong[0], ok[1], wrong[1]);
  EXPECT_GE(ok[1], ok[0]);
  EXPECT_LT(wrong[1], wrong[0]);
}

}  // namespace

TEST(Detector, ANestedPoseGivesWayToThePoseAroundIt) {
  // A section seen from far and nearly edge-on collapses onto the outline of one of its own
  // walls: under blur that nested pose can outscore the truth. It gives way to a distinct pose
  // around it that stands out in colour and explains as many edge samples
  // (detect.verify.enclosing_factor). Counted with and without it (measured: 26 found, 6 wrong
  // without; 27 and 5 with; today, plateau off, 27 and 7 without, 29 and 5 with). Most such poses
  // lie below the view range searched and are dropped first (detect.verify.view_margin): here they
  // are kept, to see the rule.
  // Blurred edges are matched at their strongest pixel here (detect.verify.plateau 0), as when the
  // rule was measured: matched at their centroids, few such poses are left to count
  // (bench/detection_eval, 120 renders a cell, plateau on: 3423 found and 56 wrong of 3600 with the
  // rule, 3422 and 57 without).
  Fixture f = make(synth::ship_section_cao);
  f.params.verify.view_margin_deg = 180.0;
  f.params.verify.plateau_px = 0.0;
  expect_fewer_wrong_on_blurred_renders(f, [](DetectorParams& p, bool on) {
    p.verify.enclosing_factor = on ? DetectorParams{}.verify.enclosing_factor : 0.0;
  });
}

TEST(Detector, AHypothesisRefinedOutOfTheViewRangeIsDropped) {
  // The far, edge-on section on one wall's outline lies below the elevations searched: dropped
  // (detect.verify.view_margin). Counted with and without the drop, and without the nested-pose
  // rule (measured: 26 found, 6 wrong without; 29 and 3 with; today, plateau off, 27 and 7
  // without, 29 and 3 with).
  // Blurred edges are matched at their strongest pixel here (detect.verify.plateau 0), as when the
  // rule was measured. Matched at their centroids, these 40 renders show no gain (36 found either
  // way, 3 wrong without, 4 with); bench/detection_eval's 3600 renders (120 a cell) do: 3423 found
  // and 56 wrong with the drop, 3413 and 67 without.
  Fixture f = make(synth::ship_section_cao);
  f.params.verify.enclosing_factor = 0.0;
  f.params.verify.plateau_px = 0.0;
  expect_fewer_wrong_on_blurred_renders(f, [](DetectorParams& p, bool on) {
    p.verify.view_margin_deg = on ? DetectorParams{}.verify.view_margin_deg : 180.0;
  });
}

TEST(Detector, TheMedoidOfNearPosesScoringAlikeIsRankedFirst) {
  // A small box under blur: refinements from different templates stop some degrees apart, all
  // scoring alike; the verified poses within detect.verify.consensus_deg / consensus_m of the best
  // and consensus_score of its score scatter around the truth, and their medoid is ranked first.
  // Counted with and without it (measured: 35 found, 5 wrong without; 36 and 4 with; today,
  // plateau off, 32 and 8 without, 34 and 6 with).
  // Blurred edges are matched at their strongest pixel here (detect.verify.plateau 0), as when the
  // rule was measured: matched at their centroids, few such poses are left to count
  // (bench/detection_eval, 120 renders a cell, plateau on: 3423 found and 56 wrong of 3600 with it,
  // 3424 and 55 without; 232 found and 11 wrong of 288 frames of the development benchmark with it,
  // 231 and 12 without).
  Fixture f = make(synth::box_cao);
  f.params.verify.plateau_px = 0.0;
  expect_fewer_wrong_on_blurred_renders(f, [](DetectorParams& p, bool on) {
    p.verify.consensus_score = on ? DetectorParams{}.verify.consensus_score : 0.0;
  });
}

TEST(Detector, WithNothingVerifiedTheNextCandidatesAreTried) {
  // A third of the object hidden: its view can rank below the first max_hypotheses candidates.
  // When none of those is verified, detect.search.extra_hypotheses more are refined and verified.
  // Counted with and without them over box, section and mockup renders (two sets of 40 each;
  // measured: 178 found, 6 wrong without; 186 and 8 with; since the continued-edge rule, 178 and
  // 5 without, 187 and 6 with): more poses tried find more and verify
  // a few more wrong ones, at least twice as many found as wrong gained.
  ASSERT_GT(DetectorParams{}.search.extra_hypotheses, 0);
  int ok[2] = {0, 0}, wrong[2] = {0, 0};
  for (std::string (*cao)() : {synth::box_cao, synth::ship_section_cao, synth::ship_mockup_cao}) {
    Fixture f = make(cao);
    for (int on = 0; on < 2; ++on) {
      f.params.search.extra_hypotheses = on == 1 ? DetectorParams{}.search.extra_hypotheses : 0;
      for (unsigned seed : {900u, 1900u}) {
        const auto [o, w] = run(f, scenes::Scene::kOcclusion, 40, seed);
        ok[on] += o;
        wrong[on] += w;
      }
    }
  }
  std::printf("without: %d found, %d wrong; with: %d found, %d wrong\n", ok[0], wrong[0], ok[1], wrong[1]);
  EXPECT_GT(ok[1], ok[0]);
  EXPECT_GE(ok[1] - ok[0], wrong[1] - wrong[0]);
}

TEST(Detector, ANearSymmetricTwinLeavesAPoseVerifiedByColourToTheTwinTest) {
  // The section turned about its vertical axis differs only by 2 cm of wall: a pose verified by
  // colour and its twin often both pass, and as rivals within colour_ambiguity they withdrew each
  // other; the twin test (twin_margin) judges such a pair instead. Counted with and without
  // (detect.verify.twins_ambiguous) over noisy, blurred, cluttered and partly hidden section
  // renders seen from all sides (measured: 135 found, 5 wrong with twins ambiguous; 138 and 6
  // judged; since detect.verify.run_gap: 136 and 4, 138 and 6): more found, and at least as many
  // found as wrong gained (twice as many before run_gap; on the whole evaluation the two settings
  // now find the same, see the README).
  Fixture f = make(synth::ship_section_cao, Views::kAllAzimuths);
  int ok[2] = {0, 0}, wrong[2] = {0, 0};
  for (int on = 0; on < 2; ++on) {
    f.params.verify.twins_ambiguous = on == 0;
    std::tie(ok[on], wrong[on]) = run_scenes(
        f, {scenes::Scene::kNoise, scenes::Scene::kBlur, scenes::Scene::kClutter, scenes::Scene::kOcclusion}, 40, 1100);
  }
  std::printf("ambiguous: %d found, %d wrong; judged: %d found, %d wrong\n", ok[0], wrong[0], ok[1], wrong[1]);
  EXPECT_GT(ok[1], ok[0]);
  EXPECT_GE(ok[1] - ok[0], wrong[1] - wrong[0]);
}

namespace {

/// Found and wrong over 40 renders of scene `s` each as bench/detection_eval makes them (the
/// fixture's view range; poses from seed 1000 + 77 x the scene's index, renders from 100), with
/// a rule off (`set(params, false)`, index 0) and on (index 1); added to ok and wrong.
void count_eval_renders(Fixture& f, scenes::Scene s, const std::function<void(DetectorParams&, bool)>& set,
                        std::array<int, 2>& ok, std::array<int, 2>& wrong) {
  for (int on = 0; on < 2; ++on) {
    set(f.params, on == 1);
    const auto [o, w] = run(f, s, 40, 1000u + static_cast<unsigned>(s) * 77u, 100u);
    ok[on] += o;
    wrong[on] += w;
  }
}

/// count_eval_renders over the box in scene `box_scene` and the ship section in `section_scene`
/// (the whole view range, as bench/detection_eval).
void count_box_and_section(scenes::Scene box_scene, scenes::Scene section_scene,
                           const std::function<void(DetectorParams&, bool)>& set, std::array<int, 2>& ok,
                           std::array<int, 2>& wrong) {
  Fixture box = make(synth::box_cao, Views::kDefault);
  count_eval_renders(box, box_scene, set, ok, wrong);
  Fixture section = make(synth::ship_section_cao, Views::kDefault);
  count_eval_renders(section, section_scene, set, ok, wrong);
}

}  // namespace

TEST(Detector, AFaceSeenEdgeOnIsUnfolded) {
  // A box seen from high above shows a side face as a thin strip below its top: the alignment
  // pulls both edges of the strip onto the stronger one and stops with the face turned out of
  // view, 5..6 degrees off, its fewer edge samples nearly all matched. The best verified pose is
  // turned to see such faces (detect.verify.unfold_*), polished and kept where it scores better.
  // Counted with and without on the renders of bench/detection_eval's textured and noisy box
  // scenes (the whole view range, the evaluation's seeds; measured: 76 found, 4 wrong without;
  // 79 and 1 with): more found, fewer wrong.
  Fixture f = make(synth::box_cao, Views::kDefault);
  std::array<int, 2> ok{}, wrong{};
  const auto unfold = [](DetectorParams& p, bool on) { p.verify.unfold_faces = on ? DetectorParams{}.verify.unfold_faces : 0; };
  for (const scenes::Scene s : {scenes::Scene::kTextured, scenes::Scene::kNoise}) count_eval_renders(f, s, unfold, ok, wrong);
  std::printf("without: %d found, %d wrong; with: %d found, %d wrong\n", ok[0], wrong[0], ok[1], wrong[1]);
  EXPECT_GT(ok[1], ok[0]);
  EXPECT_LT(wrong[1], wrong[0]);
}

TEST(Detector, AnEdgeAlongAnOccludersSideDoesNotCount) {
  // A box 30 % hidden behind a bar: a pose turned 90 degrees, one of its sides on the bar's side,
  // outscored the truth. The bar's side goes on past that pose's corners; an edge whose line the
  // image continues past both ends does not count (detect.verify.continued_*). Counted with and
  // without on the renders of bench/detection_eval's occluded box and cluttered section scenes
  // (the whole view range, the evaluation's seeds; measured: 71 found, 5 wrong without; 73 and 5
  // with): more found, no more wrong.
  std::array<int, 2> ok{}, wrong{};
  const auto continued = [](DetectorParams& p, bool on) {
    p.verify.continued_reach = on ? DetectorParams{}.verify.continued_reach : 0.0;
  };
  count_box_and_section(scenes::Scene::kOcclusion, scenes::Scene::kClutter, continued, ok, wrong);
  std::printf("without: %d found, %d wrong; with: %d found, %d wrong\n", ok[0], wrong[0], ok[1], wrong[1]);
  EXPECT_GT(ok[1], ok[0]);
  EXPECT_LE(wrong[1], wrong[0]);
}

TEST(Detector, ARunOfMatchesGoesOnOverASingleMiss) {
  // Motion blur and an occluder's boundary leave single unmatched samples along an edge that
  // break its runs of matches, and a broken run shorter than min_run does not count: the true
  // pose of a blurred box or of a section 30 % hidden scored below the bar. A run now goes on over
  // one unmatched sample when a match of its polarity follows (detect.verify.run_gap). Counted
  // with and without on the renders of bench/detection_eval's blurred box and occluded section
  // scenes (the whole view range, the evaluation's seeds; measured: 63 found, 4 wrong without;
  // 66 and 3 with): more found, no more wrong.
  std::array<int, 2> ok{}, wrong{};
  const auto gap = [](DetectorParams& p, bool on) { p.verify.run_gap = on ? DetectorParams{}.verify.run_gap : 0; };
  count_box_and_section(scenes::Scene::kBlur, scenes::Scene::kOcclusion, gap, ok, wrong);
  std::printf("without: %d found, %d wrong; with: %d found, %d wrong\n", ok[0], wrong[0], ok[1], wrong[1]);
  EXPECT_GT(ok[1], ok[0]);
  EXPECT_LE(wrong[1], wrong[0]);
}
