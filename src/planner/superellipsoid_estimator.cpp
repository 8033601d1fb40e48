#include <fruit_shape_completion/planner/superellipsoid_estimator.h>

#include <chrono>

namespace fruit_shape_completion {
namespace planner {

SuperellipsoidEstimator::SuperellipsoidEstimator(const SuperellipsoidEstimatorParams& params)
    : params_(params), map_(params.map), integrator_(params.integrator), pipeline_(params.pipeline) {}

void SuperellipsoidEstimator::insertView(const ViewData& view) {
  std::lock_guard<std::mutex> lock(mutex_);
  last_ = integrator_.integrate(map_, view.fruit_cloud, view.sensor_pose);
  dirty_ = dirty_ || last_.rays > 0;
  ++totals_.views;
  totals_.views_refused += last_.ok() ? 0 : 1;
  totals_.points_skipped += last_.non_finite + last_.out_of_range;
  totals_.rays_outside += last_.outside_map;
  totals_.rays_over_budget += last_.over_budget;
}

EstimatorStatus SuperellipsoidEstimator::status() const {
  std::lock_guard<std::mutex> lock(mutex_);
  EstimatorStatus s = totals_;
  s.blocks = map_.blockCount();
  s.max_blocks = map_.params().maxBlocks();
  s.memory_mb = static_cast<double>(map_.memoryBytes()) / 1048576.0;
  return s;
}

void SuperellipsoidEstimator::update() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!dirty_) return;
  const auto start = std::chrono::steady_clock::now();
  surface_ = extractSurfacePoints(map_, params_.surface);
  surface_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  pipeline_.update(surface_);
  dirty_ = false;
}

std::vector<FruitEstimate> SuperellipsoidEstimator::fruits() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<FruitEstimate> out;
  for (const auto& f : pipeline_.fruits())
    if (f.accepted) out.push_back(f);
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
  totals_ = EstimatorStatus();
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

PipelineStats SuperellipsoidEstimator::lastPipelineStats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return pipeline_.lastStats();
}

double SuperellipsoidEstimator::lastSurfaceSeconds() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return surface_seconds_;
}

}  // namespace planner
}  // namespace fruit_shape_completion
