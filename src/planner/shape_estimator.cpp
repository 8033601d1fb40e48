#include <fruit_shape_completion/planner/shape_estimator.h>

#include <iostream>

namespace fruit_shape_completion {
namespace planner {

void ShapeEstimatorHost::add(std::unique_ptr<ShapeEstimator> estimator) {
  if (!estimator) return;
  estimators_.push_back(std::move(estimator));
  enabled_.push_back(1);
}

void ShapeEstimatorHost::fail(std::size_t i, const std::string& what) const {
  enabled_[i] = 0;
  const std::string msg = "shape estimator '" + estimators_[i]->name() + "' disabled: " + what;
  errors_.push_back(msg);
  std::cerr << msg << "\n";
}

template <typename Call>
bool ShapeEstimatorHost::guarded(std::size_t i, Call&& call) const {
  try {
    call(*estimators_[i]);
    return true;
  } catch (const std::exception& e) {
    fail(i, e.what());
  } catch (...) {
    fail(i, "unknown exception");
  }
  return false;
}

void ShapeEstimatorHost::onView(const ViewData& view) {
  for (std::size_t i = 0; i < estimators_.size(); ++i)
    if (enabled_[i])
      guarded(i, [&](ShapeEstimator& e) {
        e.insertView(view);
        e.update();
      });
}

PointList ShapeEstimatorHost::extraTargets() const {
  PointList all;
  for (std::size_t i = 0; i < estimators_.size(); ++i) {
    PointList t;
    if (enabled_[i] && guarded(i, [&](ShapeEstimator& e) { t = e.extraTargets(); }))
      for (const auto& p : t)
        if (p.allFinite()) all.push_back(p);
  }
  return all;
}

std::vector<FruitEstimate> ShapeEstimatorHost::fruits(std::size_t i) const {
  std::vector<FruitEstimate> f;
  if (enabled(i)) guarded(i, [&](ShapeEstimator& e) { f = e.fruits(); });  // f stays empty if it throws
  return f;
}

void ShapeEstimatorHost::reset() {
  for (std::size_t i = 0; i < estimators_.size(); ++i)
    if (guarded(i, [](ShapeEstimator& e) { e.reset(); })) enabled_[i] = 1;
}

}  // namespace planner
}  // namespace fruit_shape_completion
