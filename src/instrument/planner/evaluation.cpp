#include <fruit_shape_completion/instrument/planner/evaluation.h>

#include <algorithm>
#include <cmath>
#include <tuple>

namespace fruit_shape_completion {
namespace planner {

Evaluation evaluate(const std::vector<FruitEstimate>& detected, const std::vector<TruthFruit>& truth,
                    double max_distance) {
  std::vector<std::tuple<double, int, int>> pairs;
  for (int d = 0; d < static_cast<int>(detected.size()); ++d)
    for (int t = 0; t < static_cast<int>(truth.size()); ++t) {
      const double dist = (detected[d].center() - truth[t].center).norm();
      if (dist <= max_distance) pairs.emplace_back(dist, d, t);
    }
  std::sort(pairs.begin(), pairs.end());
  std::vector<char> used_d(detected.size(), 0), used_t(truth.size(), 0);
  Evaluation ev;
  auto add = [](SubsetStats& s, double dist, double acc) {
    ++s.fruits;
    s.center_error_cm += 100.0 * dist;
    s.accuracy += acc;
  };
  for (const auto& [dist, d, t] : pairs) {
    if (used_d[d] || used_t[t]) continue;
    used_d[d] = used_t[t] = 1;
    const double acc = 1.0 - std::abs(detected[d].volume - truth[t].volume) / truth[t].volume;
    add(ev.all, dist, acc);
    if (acc > 0.0) add(ev.ma0, dist, acc);
    if (acc > 0.5) add(ev.ma50, dist, acc);
  }
  for (SubsetStats* s : {&ev.all, &ev.ma0, &ev.ma50})
    if (s->fruits > 0) {
      s->center_error_cm /= s->fruits;
      s->accuracy /= s->fruits;
    }
  return ev;
}

}  // namespace planner
}  // namespace fruit_shape_completion
