#include <fruit_shape_completion/planner/shape_estimator.h>
#include <fruit_shape_completion/planner/superellipsoid_estimator.h>

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

std::vector<EstimatedFruit> ShapeEstimatorHost::fruits(std::size_t i) const {
  std::vector<EstimatedFruit> f;
  if (enabled(i)) guarded(i, [&](ShapeEstimator& e) { f = e.fruits(); });  // f stays empty if it throws
  return f;
}

void ShapeEstimatorHost::reset() {
  for (std::size_t i = 0; i < estimators_.size(); ++i)
    if (guarded(i, [](ShapeEstimator& e) { e.reset(); })) enabled_[i] = 1;
}

SuperellipsoidEstimator::SuperellipsoidEstimator(const SuperellipsoidEstimatorParams& params)
    : params_(params), map_(params.map), integrator_(params.integrator), pipeline_(params.pipeline) {}

void SuperellipsoidEstimator::insertView(const ViewData& view) {
  std::lock_guard<std::mutex> lock(mutex_);
  last_ = integrator_.integrate(map_, view.fruit_cloud, view.sensor_pose);
  dirty_ = dirty_ || last_.rays > 0;
}

void SuperellipsoidEstimator::update() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!dirty_) return;
  surface_ = extractSurfacePoints(map_, params_.surface);
  pipeline_.update(surface_);
  dirty_ = false;
}

std::vector<EstimatedFruit> SuperellipsoidEstimator::fruits() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<EstimatedFruit> out;
  for (const auto& f : pipeline_.fruits())
    if (f.accepted) out.push_back({f.id, f.center(), f.volume});
  return out;
}

PointList SuperellipsoidEstimator::extraTargets() const {
  std::lock_guard<std::mutex> lock(mutex_);
  PointList out;
  if (!params_.publish_targets) return out;
  for (const auto& f : pipeline_.fruits())
    if (f.accepted) out.insert(out.end(), f.missing_surface.begin(), f.missing_surface.end());
  return out;
}

void SuperellipsoidEstimator::reset() {
  std::lock_guard<std::mutex> lock(mutex_);
  map_.clear();
  pipeline_.reset();
  surface_.clear();
  dirty_ = false;
}

std::vector<FruitEstimate> SuperellipsoidEstimator::estimates() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pipeline_.fruits();
}

PointList SuperellipsoidEstimator::surface() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return surface_;
}

IntegrationReport SuperellipsoidEstimator::lastIntegration() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_;
}

}  // namespace planner
}  // namespace fruit_shape_completion
