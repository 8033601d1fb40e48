// Scoring as the paper does: estimates against the scene's red ground-truth fruits.
#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace fruit_shape_completion {
namespace planner {

SceneTruth makeSceneTruth(const std::vector<sim::FruitTruth>& fruits, double resolution) {
  SceneTruth truth;
  truth.box_resolution = resolution;
  for (const auto& f : fruits) {
    if (f.color != "red") {  // the paper scores red fruit; others may not match an estimate either
      truth.not_scored.push_back(f.center);
      continue;
    }
    truth.enclosed.push_back({f.center, f.volume});
    truth.se.push_back({f.se.t, f.se_volume});
    // Centres of the voxels holding the extreme vertices: floor(x / res) + 0.5, per axis.
    const Eigen::Vector3d lo = ((f.box_min / resolution).array().floor() + 0.5) * resolution;
    const Eigen::Vector3d hi = ((f.box_max / resolution).array().floor() + 0.5) * resolution;
    const double volume = std::max((hi - lo).prod(), std::pow(resolution, 3));  // never 0: accuracy divides by it
    truth.box.push_back({0.5 * (lo + hi), volume});
  }
  return truth;
}

std::vector<FruitEstimate> SceneTruth::scoredEstimates(std::vector<FruitEstimate> estimates) const {
  if (not_scored.empty()) return estimates;
  auto nearest = [](const Eigen::Vector3d& c, const std::vector<Eigen::Vector3d>& points) {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& p : points) best = std::min(best, (p - c).norm());
    return best;
  };
  std::vector<Eigen::Vector3d> scored;
  for (const auto& t : enclosed) scored.push_back(t.center);
  estimates.erase(std::remove_if(estimates.begin(), estimates.end(),
                                 [&](const FruitEstimate& e) {
                                   return nearest(e.center(), not_scored) < nearest(e.center(), scored);
                                 }),
                  estimates.end());
  return estimates;
}

std::vector<FruitEstimate> scoreView(const RoiOcTree& tree, const SceneTruth& truth,
                                     const std::vector<FruitEstimate>& estimates, ViewRecord* rec) {
  std::vector<FruitEstimate> old_fruits, se_fruits;
  for (const auto& c : tree.roiClusters(10)) old_fruits.push_back(FruitEstimate::ofBox(c.center(), c.volume()));
  old_fruits = truth.scoredEstimates(std::move(old_fruits));
  se_fruits = truth.scoredEstimates(estimates);
  rec->old_true = evaluate(old_fruits, truth.enclosed);
  rec->se_true = evaluate(se_fruits, truth.enclosed);
  rec->old_se = evaluate(old_fruits, truth.se);
  rec->se_se = evaluate(se_fruits, truth.se);
  rec->old_box = evaluate(old_fruits, truth.box);
  return se_fruits;
}

}  // namespace planner
}  // namespace fruit_shape_completion
