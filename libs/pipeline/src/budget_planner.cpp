// v4r - robust model-based object tracking. MIT licence.
#include "v4r/pipeline/budget_planner.hpp"

#include <algorithm>

namespace v4r::pipeline {

BudgetPlan BudgetPlanner::plan(scene::Scene& scene, const CycleParams& cycle) {
  BudgetPlan plan;
  plan.rows_per_line = cycle.track.rows;
  plan.samples_per_circle = cycle.ellipse.max_samples;
  if (p_.cycle_ms <= 0.0) return plan;
  const double available_us = p_.cycle_ms * 1000.0 * (1.0 - p_.reserve_fraction);
  const double cost = p_.cost_per_sample_us;
  auto predicted_us = [&](int rows, int circle_samples) {
    long samples = 0;
    for (const scene::Object& o : scene.objects()) {
      if (!scene::is_tracked(o.status)) continue;
      for (const scene::View& v : o.views) {
        for (const scene::LineFeature& f : v.lines)
          if (f.visible && !f.ambiguous && !f.dropped) samples += rows;
        for (const scene::ArcFeature& a : v.arcs)
          if (a.visible && !a.dropped) samples += std::min(a.samples, circle_samples);
      }
    }
    return static_cast<double>(samples) * cost;
  };
  if (predicted_us(plan.rows_per_line, plan.samples_per_circle) <= available_us) return plan;
  // Level 1: fewer samples per feature (the windows keep their size).
  plan.degrade_level = 1;
  plan.rows_per_line = std::max(3, p_.reduced_rows);
  plan.samples_per_circle = std::max(8, cycle.ellipse.max_samples / 2);
  if (predicted_us(plan.rows_per_line, plan.samples_per_circle) <= available_us) return plan;
  // Level 2: leave out the least informative features: the shortest projected edges first
  // (ellipses, which constrain several degrees of freedom, count as long as their circumference).
  plan.degrade_level = 2;
  scores_.clear();
  for (const scene::Object& o : scene.objects()) {
    if (!scene::is_tracked(o.status)) continue;
    for (const scene::View& v : o.views) {
      for (const scene::LineFeature& f : v.lines)
        if (f.visible && !f.ambiguous) scores_.push_back(static_cast<float>((f.predicted.b - f.predicted.a).norm()));
      for (const scene::ArcFeature& a : v.arcs)
        if (a.visible) scores_.push_back(1e6f);
    }
  }
  const double per_feature = plan.rows_per_line * cost;
  const long keep = std::max<long>(static_cast<long>(available_us / std::max(per_feature, 1e-9)), cycle.min_lines);
  if (keep >= static_cast<long>(scores_.size())) return plan;
  std::nth_element(scores_.begin(), scores_.end() - keep, scores_.end());
  const float threshold = *(scores_.end() - keep);
  long to_drop = static_cast<long>(scores_.size()) - keep;
  for (scene::Object& o : scene.objects()) {
    for (scene::View& v : o.views) {
      for (scene::LineFeature& f : v.lines) {
        if (to_drop <= 0) break;
        if (f.visible && !f.ambiguous && static_cast<float>((f.predicted.b - f.predicted.a).norm()) < threshold) {
          f.dropped = true;
          --to_drop;
          ++plan.features_dropped;
        }
      }
    }
  }
  return plan;
}

void BudgetPlanner::learn(double track_ms, long samples) {
  if (!p_.adapt || samples <= 0 || !(track_ms > 0.0)) return;
  const double measured = track_ms * 1000.0 / static_cast<double>(samples);
  p_.cost_per_sample_us = 0.8 * p_.cost_per_sample_us + 0.2 * measured;
}

}  // namespace v4r::pipeline
