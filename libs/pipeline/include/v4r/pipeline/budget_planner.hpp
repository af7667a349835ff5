// v4r - robust model-based object tracking. MIT licence.
#pragma once

#include <vector>

#include "v4r/pipeline/cycle_params.hpp"
#include "v4r/scene/scene.hpp"

namespace v4r::pipeline {

/// \brief What the budget allows this cycle.
struct BudgetPlan {
  int degrade_level = 0;       ///< 0 none, 1 fewer samples, 2 features left out
  int rows_per_line = 0;       ///< window rows per line feature
  int samples_per_circle = 0;  ///< ellipse tracking lines beyond this take every other one
  int features_dropped = 0;    ///< left out this cycle (LineFeature::dropped set)
};

/// \brief The time budget of a cycle (paper 3.4, BudgetParams): predicts the tracking cost of
/// the visible features and degrades when it would overrun (fewer samples, then the least
/// informative features left out); learns the cost of a sample from measured tracking times.
class BudgetPlanner {
 public:
  explicit BudgetPlanner(const BudgetParams& p) : p_(p) {}
  void reserve(std::size_t features) {
    if (scores_.capacity() < features) scores_.reserve(features);
  }
  /// Plans this cycle for the objects being tracked (marks dropped features).
  BudgetPlan plan(scene::Scene& scene, const CycleParams& cycle);
  /// Learns the cost of one sample from a cycle's tracking time.
  void learn(double track_ms, long samples);
  [[nodiscard]] double cost_per_sample_us() const { return p_.cost_per_sample_us; }

 private:
  BudgetParams p_;
  std::vector<float> scores_;  // informativeness per feature
};

}  // namespace v4r::pipeline
