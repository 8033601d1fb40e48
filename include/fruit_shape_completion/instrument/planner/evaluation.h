#pragma once
// Old vs SE evaluation as in the paper: estimated fruits are matched to ground truth greedily
// by centre distance, one to one, at most max_distance apart; volume accuracy
// acc = 1 - |V_det - V_gt| / V_gt; subsets all matches, MA0 (acc > 0) and MA50 (acc > 0.5).
#include <fruit_shape_completion/host/shape_estimator.h>

#include <vector>

namespace fruit_shape_completion {
namespace planner {

struct TruthFruit {
  Eigen::Vector3d center;
  double volume;
};

struct SubsetStats {
  int fruits = 0;
  double center_error_cm = 0.0;  // mean over the subset (0 if empty)
  double accuracy = 0.0;         // mean volume accuracy over the subset (0 if empty)
};

struct Evaluation {
  SubsetStats all, ma0, ma50;
};

Evaluation evaluate(const std::vector<FruitEstimate>& detected, const std::vector<TruthFruit>& truth,
                    double max_distance = 0.2);

}  // namespace planner
}  // namespace fruit_shape_completion
