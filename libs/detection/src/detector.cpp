// v4r - robust model-based object tracking. MIT licence.
#include "v4r/detection/detector.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "v4r/core/clock.hpp"
#include "v4r/detection/symmetry.hpp"
#include "v4r/detection/view_range.hpp"
#include "v4r/model/model_colour.hpp"

namespace v4r::detection {

Detector::Detector(std::shared_ptr<const model::Model> model, std::shared_ptr<const TemplateSet> templates,
                   const geometry::PinholeCamera& cam, const DetectorParams& p)
    : model_(std::move(model)),
      templates_(std::move(templates)),
      cam_(cam),
      p_(p),
      pyramid_(cam.width, cam.height, p.search.fine_spread, p.search.coarse_spread),
      aligner_(*model_, cam, p),
      symmetries_(model_symmetries(*model_)),
      near_symmetries_(near_symmetries(*model_, p.verify.near_symmetry)),
      range_(resolve_view_range(p.views, model_extent(*model_).radius, cam.focal())),
      grazing_(*model_) {
  if (symmetries_.empty()) symmetries_.emplace_back();
  if (p_.colour.enabled)
    if (const auto rgb = model::dominant_face_colour(*model_)) {
      colour_ = std::make_unique<ColourRegions>(*model_, *templates_, cam_, *rgb, p_.colour);
      if (!colour_->usable()) colour_.reset();
    }
  coarse_.reserve(static_cast<std::size_t>(std::max(p_.search.coarse_candidates, p_.colour.coarse_candidates)) + 1);
  std::size_t max_children = 0;
  for (std::size_t k = 0; k + 1 < templates_->child_offsets.size(); ++k)
    max_children = std::max<std::size_t>(max_children, templates_->child_offsets[k + 1] - templates_->child_offsets[k]);
  fine_.reserve(static_cast<std::size_t>(std::max(p_.search.fine_expand, p_.colour.fine_expand)) * max_children + 1);
  picked_.reserve(static_cast<std::size_t>(p_.search.max_hypotheses + p_.search.extra_hypotheses));
  work_.reserve(static_cast<std::size_t>(p_.search.max_hypotheses + p_.search.extra_hypotheses));
}

namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;
// detect.search.fine_window is at most 8 (its registered range): at most 18 x 18 anchors.
constexpr int kMaxFineWindow = 8;
constexpr double kPolishScoreDrop = 0.02;  // a polished pose may score this much less than before
constexpr int kTieMinSamples = 10;          // distinctive edge samples each pose of a near tie needs
constexpr std::size_t kMaxConsensus = 32;   // members of a consensus cluster considered, at most
constexpr std::size_t kMaxFineAnchors = (2 * kMaxFineWindow + 2) * (2 * kMaxFineWindow + 2);
// Adjacent coarse anchors summed together (the linear maps are padded for a row's last tile).
constexpr int kCoarseTile = 32;
static_assert(kCoarseTile <= kLinearPadding);
// 16 bytes added lane by lane (GCC's and Clang's vector extension: SSE2, NEON, or plain code).
using Bytes16 = std::uint8_t __attribute__((vector_size(16)));
inline Bytes16 load16(const std::uint8_t* p) {
  Bytes16 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
GradientThreshold search_threshold(const SearchParams& s) { return {s.min_gradient, s.min_gradient_floor, s.noise_factor}; }

/// Sums over features of 16 adjacent anchors in each of NY rows `w` apart: `base[f] + off`
/// is feature f's response at the first of them. Written to `out`, rows `out_stride` apart. With
/// NY known the sums stay in registers.
template <int NY>
void sum_rows(const std::uint8_t* const* base, std::uint32_t count, std::size_t off, std::size_t w, std::uint8_t* out,
              int out_stride) {
  Bytes16 a[NY] = {};
  for (std::uint32_t f = 0; f < count; ++f)
    for (int iy = 0; iy < NY; ++iy) a[iy] += load16(base[f] + off + iy * w);
  for (int iy = 0; iy < NY; ++iy) std::memcpy(out + iy * out_stride, &a[iy], sizeof a[iy]);
}
}  // namespace

bool Detector::set_image(const image::ColourView& bgr) { return pyramid_.compute(bgr, search_threshold(p_.search)); }
bool Detector::set_image(const image::ImageView& grey) { return pyramid_.compute(grey, search_threshold(p_.search)); }
Verification Detector::verify(const geometry::SE3& T) { return aligner_.verify(pyramid_, T); }
int Detector::refine(geometry::SE3& T) { return aligner_.refine(pyramid_, T); }
int Detector::polish(geometry::SE3& T) { return aligner_.polish(pyramid_, T); }
bool Detector::prefer_twin(geometry::SE3& T) {
  if (!(p_.verify.twin_margin > 0.0)) return false;
  for (const geometry::SE3& S : near_symmetries_) {
    geometry::SE3 twin;
    if (twin_verdict(T, S, twin) >= 0) continue;
    T = twin;
    return true;
  }
  return false;
}

DetectionResult Detector::detect(const image::ColourView& bgr, std::span<Hypothesis> out) {
  const auto t0 = Clock::now();
  int regions = -1;
  if (colour_) {
    regions = colour_->find(bgr);
    if (regions < 0) return DetectionResult{DetectionResult::Status::kBadImage};
  }
  const double colour_ms = ms_between(t0, Clock::now());
  if (regions == 0) {  // nothing of the model's colour: no hypothesis, no gradients
    DetectionResult r;
    r.colour_regions = 0;
    r.colour_ms = r.total_ms = colour_ms;
    return r;
  }
  use_colour_ = regions > 0;
  if (!(use_colour_ ? pyramid_.compute(bgr, search_threshold(p_.search), colour_roi()) : set_image(bgr)))
    return DetectionResult{DetectionResult::Status::kBadImage};
  frame_colour_ = bgr;
  DetectionResult r = run(out);
  frame_colour_ = image::ColourView{};
  use_colour_ = false;
  r.colour_regions = regions;
  r.colour_ms = colour_ms;
  r.gradient_ms = ms_between(t0, Clock::now()) - r.search_ms - r.refine_ms - colour_ms;
  r.total_ms = ms_between(t0, Clock::now());
  return r;
}

DetectionResult Detector::detect(const image::ImageView& grey, std::span<Hypothesis> out) {
  const auto t0 = Clock::now();
  if (!set_image(grey)) return DetectionResult{DetectionResult::Status::kBadImage};
  DetectionResult r = run(out);
  r.gradient_ms = ms_between(t0, Clock::now()) - r.search_ms - r.refine_ms;
  r.total_ms = ms_between(t0, Clock::now());
  return r;
}

void Detector::coarse_search() {
  const TemplateSet& ts = *templates_;
  const OrientationLevel& L = pyramid_.coarse();
  coarse_.clear();
  int worst = 0;  // smallest score in coarse_ once it is full
  for (std::size_t k = 0; k < ts.coarse.templates.size(); ++k) {
    const Template& t = ts.coarse.templates[k];
    if (t.count < 4) continue;
    // Anchors (2i, 2j) whose template lies inside the level.
    const int i0 = std::max(0, (-t.x0 + 1) / 2), j0 = std::max(0, (-t.y0 + 1) / 2);
    const int i1 = (L.width - 1 - t.x1) / 2, j1 = (L.height - 1 - t.y1) / 2;
    if (i1 < i0 || j1 < j0 || 2 * i1 + t.x1 > L.width - 1 || 2 * j1 + t.y1 > L.height - 1) continue;
    if (!use_colour_) {
      scan_coarse(k, i0, j0, i1, j1, worst);
      continue;
    }
    // Only where the template's coloured footprint holds a colour region of matching area.
    for (const ColourRegion& reg : colour_->regions()) {
      int ax0 = 0, ay0 = 0, ax1 = 0, ay1 = 0;
      if (!colour_->anchor_window(k, reg, ax0, ay0, ax1, ay1)) continue;
      const int ilo = std::max(i0, (ax0 + 1) / 2), ihi = std::min(i1, ax1 / 2);
      const int jlo = std::max(j0, (ay0 + 1) / 2), jhi = std::min(j1, ay1 / 2);
      if (ilo > ihi || jlo > jhi) continue;
      scan_coarse(k, ilo, jlo, ihi, jhi, worst);
    }
  }
}

void Detector::scan_coarse(std::size_t k, int ilo, int jlo, int ihi, int jhi, int& worst) {
  const TemplateSet& ts = *templates_;
  const OrientationLevel& L = pyramid_.coarse();
  const int lw = L.lin_width;
  const std::size_t K = static_cast<std::size_t>(use_colour_ ? p_.colour.coarse_candidates : p_.search.coarse_candidates);
  const Template& t = ts.coarse.templates[k];
  const int aw = ihi - ilo + 1, ah = jhi - jlo + 1;
  // Each feature's response at the anchor (ilo, jlo); anchor (ilo + i, jlo + j) is j * lw + i on.
  std::array<const std::uint8_t*, 64> src;
  const std::uint32_t count = std::min<std::uint32_t>(t.count, 64);
  for (std::uint32_t q = 0; q < count; ++q) {
    const Feature& ft = ts.coarse.features[t.first + q];
    const int px = ft.x & 1, py = ft.y & 1;
    const int dx = (ft.x - px) / 2, dy = (ft.y - py) / 2;
    src[q] = L.linear[ft.orientation][py * 2 + px].data() + static_cast<std::size_t>(jlo + dy) * lw + (ilo + dx);
  }
  // Tiles of 32 adjacent anchors of a row, their sums in two vector registers through all the
  // features (the maps are padded for a row's last tile, whose lanes past the row are summed too
  // and then set to 0), then the best anchor in row order (the first of equal sums).
  int best = -1, bi = 0, bj = 0;
  for (int j = 0; j < ah; ++j) {
    const std::size_t row = static_cast<std::size_t>(j) * lw;
    for (int i0 = 0; i0 < aw; i0 += kCoarseTile) {
      // The tile's two halves as two "rows" 16 bytes apart.
      std::uint8_t a[kCoarseTile];
      sum_rows<kCoarseTile / 16>(src.data(), count, row + static_cast<std::size_t>(i0), 16, a, 16);
      // Lanes past the row count 0: never above an earlier lane of the row.
      const int lanes = std::min(kCoarseTile, aw - i0);
      std::fill(a + lanes, a + kCoarseTile, std::uint8_t{0});
      std::uint8_t m = 0;
      for (int l = 0; l < kCoarseTile; ++l) m = std::max(m, a[l]);
      if (m <= best) continue;
      best = m;
      bi = i0 + static_cast<int>(std::find(a, a + kCoarseTile, m) - a);
      bj = j;
    }
  }
  const int min_score = static_cast<int>(std::ceil(p_.search.coarse_min_score * 4.0 * t.count));
  if (best < min_score) return;
  // Scores compared as shares of each template's best possible score (x1000).
  const int share = static_cast<int>(1000.0 * best / (4.0 * t.count));
  if (coarse_.size() >= K && share <= worst) return;
  Candidate c{share, static_cast<std::uint32_t>(k), static_cast<std::int16_t>(2 * (ilo + bi)),
              static_cast<std::int16_t>(2 * (jlo + bj))};
  if (coarse_.size() < K) {
    coarse_.push_back(c);
  } else {
    auto it = std::min_element(coarse_.begin(), coarse_.end(), [](const Candidate& a, const Candidate& b) { return a.score < b.score; });
    *it = c;
  }
  if (coarse_.size() >= K)
    worst = std::min_element(coarse_.begin(), coarse_.end(), [](const Candidate& a, const Candidate& b) { return a.score < b.score; })->score;
}

PixelBox Detector::colour_roi() const {
  const TemplateSet& ts = *templates_;
  int x0 = 1 << 20, y0 = 1 << 20, x1 = -(1 << 20), y1 = -(1 << 20);  // coarse pixels, inclusive
  for (std::size_t k = 0; k < ts.coarse.templates.size(); ++k) {
    const Template& t = ts.coarse.templates[k];
    for (const ColourRegion& reg : colour_->regions()) {
      int ax0 = 0, ay0 = 0, ax1 = 0, ay1 = 0;
      if (!colour_->anchor_window(k, reg, ax0, ay0, ax1, ay1)) continue;
      // The template's extent grown by 15 % of its size: its children at the fine level are up
      // to one distance step (detect.templates.scale_step) larger.
      const int gx = (t.x1 - t.x0) * 15 / 100 + 1, gy = (t.y1 - t.y0) * 15 / 100 + 1;
      x0 = std::min(x0, ax0 + t.x0 - gx);
      y0 = std::min(y0, ay0 + t.y0 - gy);
      x1 = std::max(x1, ax1 + t.x1 + gx);
      y1 = std::max(y1, ay1 + t.y1 + gy);
    }
  }
  if (x1 < x0) return PixelBox{};
  const int m = p_.colour.roi_margin;
  return PixelBox{4 * x0 - m, 4 * y0 - m, 4 * (x1 + 1) + m, 4 * (y1 + 1) + m};
}

int Detector::score_fine(std::uint32_t view, int cx, int cy, int& bx, int& by) const {
  const TemplateSet& ts = *templates_;
  const OrientationLevel& L = pyramid_.fine();
  const int w = L.width, h = L.height, r = std::clamp(p_.search.fine_window, 0, kMaxFineWindow);
  const Template& t = ts.fine.templates[view];
  if (t.count < 8 || t.count > 63) return -1;  // detect.templates.fine_features: 8 .. 63
  // The anchors of the window whose features all lie inside the image.
  const int ylo = std::max(cy - r, -static_cast<int>(t.y0)), yhi = std::min(cy + 1 + r, h - 1 - t.y1);
  const int xlo = std::max(cx - r, -static_cast<int>(t.x0)), xhi = std::min(cx + 1 + r, w - 1 - t.x1);
  if (ylo > yhi || xlo > xhi) return -1;
  const int nx = xhi - xlo + 1, ny = yhi - ylo + 1;
  // Blocks of 16 adjacent anchors in up to 6 rows, their sums in registers through all the
  // features (the response maps are padded for a row's last block), then the best anchor in row
  // order (the first of equal sums). Sums fit a byte: at most 63 features of 4.
  static_assert(kResponsePadding >= 16);
  const int blocks = (nx + 15) / 16, stride = blocks * 16;
  std::array<std::uint8_t, kMaxFineAnchors * 2> acc;  // ny rows of `stride` sums
  std::array<const std::uint8_t*, 64> base;            // each feature's response at anchor (xlo, ylo)
  const std::uint32_t count = t.count;                 // 8 .. 63, tested above
  for (std::uint32_t f = 0; f < count; ++f) {
    const Feature& ft = ts.fine.features[t.first + f];
    base[f] = L.response[ft.orientation].data() + static_cast<std::size_t>(ylo + ft.y) * w + (xlo + ft.x);
  }
  const std::size_t sw = static_cast<std::size_t>(w);
  for (int b = 0; b < blocks; ++b)
    for (int r0 = 0; r0 < ny; r0 += 6) {
      const std::size_t off = static_cast<std::size_t>(r0) * sw + static_cast<std::size_t>(16 * b);
      std::uint8_t* out = acc.data() + r0 * stride + 16 * b;
      switch (std::min(6, ny - r0)) {
        case 1: sum_rows<1>(base.data(), count, off, sw, out, stride); break;
        case 2: sum_rows<2>(base.data(), count, off, sw, out, stride); break;
        case 3: sum_rows<3>(base.data(), count, off, sw, out, stride); break;
        case 4: sum_rows<4>(base.data(), count, off, sw, out, stride); break;
        case 5: sum_rows<5>(base.data(), count, off, sw, out, stride); break;
        default: sum_rows<6>(base.data(), count, off, sw, out, stride); break;
      }
    }
  int best = -1;
  for (int iy = 0; iy < ny; ++iy)
    for (int ix = 0; ix < nx; ++ix)
      if (acc[static_cast<std::size_t>(iy * stride + ix)] > best) {
        best = acc[static_cast<std::size_t>(iy * stride + ix)];
        bx = xlo + ix;
        by = ylo + iy;
      }
  return best < 0 ? -1 : static_cast<int>(1000.0 * best / (4.0 * t.count));
}

void Detector::fine_search() {
  const TemplateSet& ts = *templates_;
  fine_.clear();
  // Probe: every coarse candidate's own view at the fine level ranks the candidates; only the
  // best fine_expand are expanded to their children.
  for (Candidate& c : coarse_) {
    int bx = 2 * c.x, by = 2 * c.y;
    const int s = score_fine(ts.coarse_views[c.index], 2 * c.x, 2 * c.y, bx, by);
    c.score = s;
  }
  std::sort(coarse_.begin(), coarse_.end(), [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
  const std::size_t expand =
      std::min(coarse_.size(), static_cast<std::size_t>(use_colour_ ? p_.colour.fine_expand : p_.search.fine_expand));
  for (std::size_t k = 0; k < expand; ++k) {
    const Candidate& c = coarse_[k];
    if (c.score < 0) break;
    const int cx = 2 * c.x, cy = 2 * c.y;  // 1/4 -> 1/2 resolution
    for (std::uint32_t ci = ts.child_offsets[c.index]; ci < ts.child_offsets[c.index + 1]; ++ci) {
      const std::uint32_t view = ts.children[ci];
      int bx = cx, by = cy;
      const int s = score_fine(view, cx, cy, bx, by);
      if (s < 0) continue;
      fine_.push_back(Candidate{s, view, static_cast<std::int16_t>(bx), static_cast<std::int16_t>(by)});
    }
  }
  std::sort(fine_.begin(), fine_.end(), [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
  // Distinct hypotheses: not the same place with nearly the same view.
  picked_.clear();
  const std::size_t want = first_batch() + static_cast<std::size_t>(p_.search.extra_hypotheses);
  for (const Candidate& c : fine_) {
    if (picked_.size() >= want) break;
    bool dup = false;
    for (const Candidate& q : picked_) {
      if (std::abs(q.x - c.x) > 3 || std::abs(q.y - c.y) > 3) continue;
      const TemplateView& a = ts.views[q.index];
      const TemplateView& b = ts.views[c.index];
      if (std::abs(a.distance - b.distance) <= 1 && geometry::rotation_angle_between(a.T_cam_obj, b.T_cam_obj) < 0.3) {
        dup = true;
        break;
      }
    }
    if (!dup) picked_.push_back(c);
  }
}

std::size_t Detector::first_batch() const {
  return static_cast<std::size_t>(use_colour_ ? std::min(p_.colour.max_hypotheses, p_.search.max_hypotheses)
                                             : p_.search.max_hypotheses);
}

Detector::CandidateInfo Detector::candidate(bool picked, std::size_t i) const {
  if (picked) {
    const Candidate& c = picked_[i];
    return CandidateInfo{c.index, c.score, c.x, c.y};
  }
  const Candidate& c = coarse_[i];  // coarse anchors are 1/4-resolution pixels
  return CandidateInfo{templates_->coarse_views[c.index], c.score, 2 * c.x, 2 * c.y};
}

DetectionResult Detector::run(std::span<Hypothesis> out) {
  DetectionResult r;
  const auto t0 = Clock::now();
  coarse_search();
  fine_search();
  r.coarse_candidates = static_cast<int>(coarse_.size());
  const auto t1 = Clock::now();
  r.search_ms = ms_between(t0, t1);
  work_.clear();
  const std::size_t first = first_batch();
  bool any_verified = false;
  for (std::size_t k = 0; k < picked_.size(); ++k) {
    // The extra candidates only when none of the first batch is verified.
    if (k == first && any_verified) break;
    const Candidate& c = picked_[k];
    Hypothesis h;
    h.view = c.index;
    h.template_score = c.score / 1000.0;
    h.T_cam_obj = pose_at_pixel(*templates_, c.index, cam_, 2.0 * c.x + 0.5, 2.0 * c.y + 0.5);
    h.T_template = h.T_cam_obj;
    aligner_.refine(pyramid_, h.T_cam_obj);
    // Refined out of the view range (a far pose seen edge-on, nested in the object's image):
    // not a hypothesis.
    if (p_.verify.view_margin_deg < 180.0 &&
        !in_view_range(range_, templates_->centre, symmetries_, h.T_cam_obj, p_.verify.view_margin_deg,
                       p_.verify.inplane_margin_deg))
      continue;
    h.verification = aligner_.verify(pyramid_, h.T_cam_obj);
    h.verified = h.verification.samples >= p_.verify.min_samples && h.verification.score >= p_.verify.accept_score;
    // Below the edge test's bar, but edges enough for a partly hidden, noisy or blurred view: its
    // silhouette must stand out in colour.
    if (!h.verified && !frame_colour_.empty() && h.verification.samples >= p_.verify.min_samples &&
        h.verification.score >= p_.verify.leak_score) {
      aligner_.measure_leak(frame_colour_, h.T_cam_obj, h.verification);
      h.verified = h.verification.leak_samples >= p_.verify.leak_min_samples && h.verification.leak >= 0.0 &&
                   h.verification.leak <= p_.verify.max_leak;
    }
    any_verified = any_verified || h.verified;
    work_.push_back(h);
  }
  resolve_twins();
  // A pose verified by colour alone (its outline stands out, its edges score below accept_score)
  // is ambiguous when another verified pose, different beyond the symmetries (the same outline
  // turned over, say), scores within colour_ambiguity of it; one verified by its edges, within
  // edge_ambiguity (off by default). Ambiguous poses are not verified.
  if (p_.verify.colour_ambiguity > 0.0 || p_.verify.edge_ambiguity > 0.0) {
    for (Hypothesis& h : work_) h.ambiguous = false;
    for (Hypothesis& h : work_) {
      if (!h.verified) continue;
      const double margin = h.verification.score >= p_.verify.accept_score ? p_.verify.edge_ambiguity : p_.verify.colour_ambiguity;
      if (margin <= 0.0) continue;
      for (const Hypothesis& o : work_) {
        if (&o == &h || !o.verified || o.verification.score < h.verification.score - margin) continue;
        if (!distinct(o.T_cam_obj, h.T_cam_obj)) continue;
        // A near-symmetric twin is no ambiguity when the twin test (resolve_twins) judged the pair.
        if (!p_.verify.twins_ambiguous && p_.verify.twin_margin > 0.0 && is_twin(o.T_cam_obj, h.T_cam_obj)) continue;
        h.ambiguous = true;
        break;
      }
    }
    for (Hypothesis& h : work_) h.verified = h.verified && !h.ambiguous;
  }
  verify_stand_out();
  std::sort(work_.begin(), work_.end(), [](const Hypothesis& a, const Hypothesis& b) {
    if (a.verified != b.verified) return a.verified;
    return a.verification.score > b.verification.score;
  });
  break_near_tie();
  give_way_to_enclosing();
  take_consensus();
  polish_best();
  unfold_best();
  // Hypotheses that converged to the same pose are given once (the best ranked).
  std::size_t n = 0;
  for (std::size_t i = 0; i < work_.size() && n < out.size(); ++i) {
    bool dup = false;
    for (std::size_t j = 0; j < n && !dup; ++j)
      dup = (out[j].T_cam_obj.translation() - work_[i].T_cam_obj.translation()).norm() < 0.01 &&
            geometry::rotation_angle_between(out[j].T_cam_obj, work_[i].T_cam_obj) < 0.035;
    if (dup) continue;
    out[n++] = work_[i];
    r.verified += work_[i].verified ? 1 : 0;
  }
  r.hypotheses = static_cast<int>(n);
  r.refine_ms = ms_between(t1, Clock::now());
  return r;
}

void Detector::verify_stand_out() {
  const VerifyParams& v = p_.verify;
  if (frame_colour_.empty() || v.stand_out_score >= v.accept_score || work_.empty()) return;
  Hypothesis* top = nullptr;
  for (Hypothesis& h : work_) {
    if (h.verified) return;
    if (top == nullptr || h.verification.score > top->verification.score) top = &h;
  }
  const bool by_leak = v.stand_out_leak_margin < 1.0;
  const auto stands_out = [&](Hypothesis& c) {
    Verification& cv = c.verification;
    if (cv.samples < v.min_samples || cv.score < v.stand_out_score) return false;
    if (cv.leak_samples == 0) aligner_.measure_leak(frame_colour_, c.T_cam_obj, cv);
    if (cv.leak_samples < v.leak_min_samples || cv.leak < 0.0 || cv.leak > v.stand_out_max_leak) return false;
    for (Hypothesis& o : work_) {
      if (&o == &c || o.verification.score < cv.score - v.stand_out_margin) continue;
      if (!distinct(o.T_cam_obj, c.T_cam_obj)) continue;  // the same pose
      // A distinct pose as good by its edges whose outline leaks much more (by the margin, and as
      // much as no pose that stands out may): an outline on clutter or on the object's own
      // print, not a rival. Its leak is measured when first needed.
      Verification& ov = o.verification;
      if (by_leak && ov.leak_samples == 0) aligner_.measure_leak(frame_colour_, o.T_cam_obj, ov);
      const double rival_leak = std::max(cv.leak + v.stand_out_leak_margin, v.stand_out_max_leak);
      if (by_leak && ov.leak_samples >= v.leak_min_samples && ov.leak >= rival_leak) continue;
      return false;
    }
    // Its near-symmetric twins (not among the hypotheses when the search found only one of them)
    // must match worse where they differ from it, or else score stand_out_margin less.
    for (const geometry::SE3& S : near_symmetries_) {
      geometry::SE3 twin;
      const int verdict = twin_verdict(c.T_cam_obj, S, twin);
      if (verdict < 0 || (verdict == 0 && aligner_.verify(pyramid_, twin).score >= cv.score - v.stand_out_margin)) return false;
    }
    return true;
  };
  if (!by_leak) {
    top->verified = stands_out(*top);
    return;
  }
  // The best-scoring pose that stands out: candidates in order of score (then of index).
  double last_score = 2.0;
  std::size_t last_index = 0;
  for (;;) {
    std::size_t c = work_.size();
    for (std::size_t i = 0; i < work_.size(); ++i) {
      const double sc = work_[i].verification.score;
      if (sc > last_score || (sc == last_score && i <= last_index)) continue;  // tried already
      if (c == work_.size() || sc > work_[c].verification.score) c = i;
    }
    if (c == work_.size() || work_[c].verification.score < v.stand_out_score) return;
    last_score = work_[c].verification.score;
    last_index = c;
    if (stands_out(work_[c])) {
      work_[c].verified = true;
      return;
    }
  }
}

int Detector::twin_verdict(const geometry::SE3& T, const geometry::SE3& S, geometry::SE3& twin) {
  constexpr int kMinDistinct = 8;  // distinctive samples each, at least
  twin = T * S;
  aligner_.refine(pyramid_, twin);
  if (!(p_.verify.twin_margin > 0.0)) return 0;
  const EdgeAligner::TwinShares t = aligner_.compare_twins(pyramid_, T, twin, 2.0 * p_.verify.match_distance_px);
  if (t.na < kMinDistinct || t.nb < kMinDistinct) return 0;
  if (t.a >= t.b + p_.verify.twin_margin) return 1;
  if (t.b >= t.a + p_.verify.twin_margin) return -1;
  // Neither ahead: the distances to the edges' centres, with the pose aligned as its twin was
  // (a pose refined by the tracker sits elsewhere on a smeared edge than the detector's alignment
  // puts its twin).
  const double rm = p_.verify.twin_residual_margin;
  if (!(rm > 0.0)) return 0;
  geometry::SE3 Ta = T;
  aligner_.refine(pyramid_, Ta);
  const EdgeAligner::TwinShares u = aligner_.compare_twins(pyramid_, Ta, twin, 2.0 * p_.verify.match_distance_px, true);
  if (u.na < kMinDistinct || u.nb < kMinDistinct) return 0;
  if (u.residual_a + rm <= u.residual_b) return 1;
  if (u.residual_b + rm <= u.residual_a) return -1;
  return 0;
}

void Detector::resolve_twins() {
  if (near_symmetries_.empty() || !(p_.verify.twin_margin > 0.0) || work_.empty()) return;
  // The best-scoring hypothesis and the best verified one (a refinement and two edge tests per
  // near symmetry each: a model with many, a near cube, would otherwise cost much).
  const Hypothesis *top = &work_.front(), *top_verified = nullptr;
  for (const Hypothesis& h : work_) {
    if (h.verification.score > top->verification.score) top = &h;
    if (h.verified && (top_verified == nullptr || h.verification.score > top_verified->verification.score)) top_verified = &h;
  }
  for (Hypothesis& h : work_)
    if (&h == top || &h == top_verified) prefer_twin(h);
}

void Detector::prefer_twin(Hypothesis& h) {
  geometry::SE3 T = h.T_cam_obj;
  if (prefer_twin(T)) move_hypothesis(h, T, aligner_.verify(pyramid_, T));
}

void Detector::move_hypothesis(Hypothesis& h, const geometry::SE3& T, const Verification& v) {
  const bool leak_measured = h.verification.leak_samples > 0;
  h.T_cam_obj = T;
  h.verification = v;
  if (leak_measured && !frame_colour_.empty()) aligner_.measure_leak(frame_colour_, T, h.verification);
}

void Detector::polish_best() {
  if (work_.empty() || !work_[0].verified || p_.verify.polish_iterations <= 0) return;
  geometry::SE3 T = work_[0].T_cam_obj;
  if (aligner_.polish(pyramid_, T) == 0) return;
  // Kept unless its edge test drops (a polish pulled onto a texture line).
  const Verification v = aligner_.verify(pyramid_, T);
  if (v.samples >= p_.verify.min_samples && v.score >= work_[0].verification.score - kPolishScoreDrop)
    move_hypothesis(work_[0], T, v);
}

void Detector::unfold_best() {
  constexpr std::size_t kMaxFaces = 8;  // detect.verify.unfold_faces is at most 8
  const VerifyParams& v = p_.verify;
  if (v.unfold_faces <= 0 || work_.empty() || !work_[0].verified) return;
  Hypothesis& best = work_[0];
  std::array<geometry::SE3, kMaxFaces> turned;
  const Eigen::Vector3d pivot = aligner_.visible_centroid(best.T_cam_obj, templates_->centre);
  const std::size_t n = grazing_.unfold(best.T_cam_obj, pivot, v.unfold_band_deg * kDeg, v.unfold_deg * kDeg,
                                        std::span<geometry::SE3>(turned).first(std::min<std::size_t>(kMaxFaces, v.unfold_faces)));
  geometry::SE3 best_T = best.T_cam_obj;
  Verification best_v = best.verification;
  for (std::size_t i = 0; i < n; ++i) {
    geometry::SE3 T = turned[i];
    aligner_.polish(pyramid_, T);
    const Verification vt = aligner_.verify(pyramid_, T);
    if (vt.samples >= v.min_samples && vt.score >= best_v.score + v.unfold_gain) {
      best_T = T;
      best_v = vt;
    }
  }
  if (best_v.score > best.verification.score) move_hypothesis(best, best_T, best_v);
}

void Detector::give_way_to_enclosing() {
  // A share of the other's box: a pose whose samples cover as much is not nested in it.
  constexpr double kEnclosedArea = 0.8;
  const VerifyParams& v = p_.verify;
  if (!(v.enclosing_factor > 0.0) || frame_colour_.empty() || work_.empty() || !work_[0].verified) return;
  Hypothesis& a = work_[0];
  const PixelBox& ab = a.verification.box;
  const double area_a = double(ab.x1 - ab.x0) * (ab.y1 - ab.y0);
  for (std::size_t i = 1; i < work_.size(); ++i) {
    Verification& bv = work_[i].verification;
    if (bv.samples < v.min_samples || bv.score < v.stand_out_score) continue;
    if (bv.in_runs < v.enclosing_factor * a.verification.in_runs) continue;
    // a's samples within b's box (a margin of 2.5 % of its size, at least 4 px), covering at
    // most kEnclosedArea of it.
    const PixelBox& bb = bv.box;
    const int m = std::max(4, (bb.x1 - bb.x0 + bb.y1 - bb.y0) / 40);
    if (ab.x0 < bb.x0 - m || ab.y0 < bb.y0 - m || ab.x1 > bb.x1 + m || ab.y1 > bb.y1 + m) continue;
    if (area_a > kEnclosedArea * double(bb.x1 - bb.x0) * (bb.y1 - bb.y0)) continue;
    if (!distinct(a.T_cam_obj, work_[i].T_cam_obj)) continue;
    // b stands out in colour, and leaks no more than a.
    if (bv.leak_samples == 0) aligner_.measure_leak(frame_colour_, work_[i].T_cam_obj, bv);
    if (bv.leak_samples < v.leak_min_samples || bv.leak < 0.0 || bv.leak > v.stand_out_max_leak) continue;
    if (a.verification.leak_samples == 0) aligner_.measure_leak(frame_colour_, a.T_cam_obj, a.verification);
    if (a.verification.leak_samples >= v.leak_min_samples && a.verification.leak < bv.leak) continue;
    a.verified = false;
    work_[i].verified = true;
    std::swap(work_[0], work_[i]);
    prefer_twin(work_[0]);
    return;
  }
}

void Detector::take_consensus() {
  const VerifyParams& v = p_.verify;
  if (!(v.consensus_score > 0.0) || !(v.consensus_deg > 0.0) || !(v.consensus_m > 0.0) || work_.empty() ||
      !work_[0].verified)
    return;
  // The cluster: verified poses (sorted first, by decreasing score) near the best one.
  const double floor = work_[0].verification.score - v.consensus_score;
  std::size_t members[kMaxConsensus];
  std::size_t n = 0;
  for (std::size_t i = 0; i < work_.size() && n < kMaxConsensus; ++i) {
    if (!work_[i].verified || work_[i].verification.score < floor) break;
    const PoseError e = symmetric_pose_error(work_[i].T_cam_obj, work_[0].T_cam_obj, symmetries_);
    if (e.rotation <= v.consensus_deg * kDeg && e.translation <= v.consensus_m) members[n++] = i;
  }
  if (n < 3) return;
  // Its medoid: the least summed distance to the others (turn and shift, each in its radius).
  std::size_t best = 0;
  double best_cost = 0.0;
  for (std::size_t a = 0; a < n; ++a) {
    double cost = 0.0;
    for (std::size_t b = 0; b < n; ++b) {
      if (a == b) continue;
      const PoseError e = symmetric_pose_error(work_[members[a]].T_cam_obj, work_[members[b]].T_cam_obj, symmetries_);
      cost += e.rotation / (v.consensus_deg * kDeg) + e.translation / v.consensus_m;
    }
    if (a == 0 || cost < best_cost) {
      best = a;
      best_cost = cost;
    }
  }
  if (best != 0) std::swap(work_[0], work_[members[best]]);
}

bool Detector::is_twin(const geometry::SE3& a, const geometry::SE3& b) const {
  for (const geometry::SE3& S : near_symmetries_)
    if (!distinct(a, b * S)) return true;
  return false;
}

bool Detector::distinct(const geometry::SE3& a, const geometry::SE3& b) const {
  const PoseError e = symmetric_pose_error(a, b, symmetries_);
  return e.translation > p_.verify.distinct_m || e.rotation > p_.verify.distinct_deg * kDeg;
}

void Detector::break_near_tie() {
  if (!(p_.verify.tie_score > 0.0) || work_.empty() || !work_[0].verified) return;
  const Hypothesis& best = work_[0];
  for (std::size_t i = 1; i < work_.size(); ++i) {
    const Hypothesis& h = work_[i];
    // (Sorted: verified first, by decreasing score.)
    if (!h.verified || h.verification.score < best.verification.score - p_.verify.tie_score) return;
    if (!distinct(h.T_cam_obj, best.T_cam_obj)) continue;
    const EdgeAligner::TwinShares t =
        aligner_.compare_twins(pyramid_, best.T_cam_obj, h.T_cam_obj, 2.0 * p_.verify.match_distance_px);
    if (t.na >= kTieMinSamples && t.nb >= kTieMinSamples && t.b > t.a + p_.verify.tie_margin) {
      std::swap(work_[0], work_[i]);
      return;
    }
  }
}

}  // namespace v4r::detection
