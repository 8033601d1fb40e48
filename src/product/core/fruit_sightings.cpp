#include <fruit_shape_completion/fruit_sightings.h>

#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {

FruitSightingLog::FruitSightingLog(std::size_t kept_views, std::size_t points_per_view)
    : kept_views_(std::max<std::size_t>(1, kept_views)), points_per_view_(std::max<std::size_t>(1, points_per_view)) {}

void FruitSightingLog::addView(double time, const PointList& fruit_points, const Eigen::Isometry3d& sensor_pose) {
  const bool finite = sensor_pose.matrix().allFinite();
  const bool same_pose =
      pose_ > 0 && finite && (sensor_pose.translation() - pose_start_.translation()).norm() < kSamePoseMove &&
      Eigen::AngleAxisd(pose_start_.linear().transpose() * sensor_pose.linear()).angle() < kSamePoseTurnDeg * M_PI / 180.0;
  if (!same_pose) {
    ++pose_;
    if (finite) pose_start_ = sensor_pose;
  }
  View v{time, pose_, {}};
  const std::size_t n = fruit_points.size(), keep = std::min(n, points_per_view_);
  v.points.reserve(keep);
  for (std::size_t i = 0; i < keep; ++i) {
    const Point& p = fruit_points[i * n / keep];
    if (p.allFinite()) v.points.push_back(p);
  }
  if (!v.points.empty()) {
    v.lo = v.hi = v.points.front();
    for (const auto& p : v.points) {
      v.lo = v.lo.cwiseMin(p);
      v.hi = v.hi.cwiseMax(p);
    }
  }
  pending_.push_back(std::move(v));
  // Fits may fall behind the views: the oldest unmatched views go first.
  while (pending_.size() > kept_views_) pending_.pop_front();
}

bool FruitSightingLog::saw(const View& view, const FruitEstimate& fruit) {
  const double reach = std::max({fruit.shape.a, fruit.shape.b, fruit.shape.c}) + 0.01;
  if (view.points.empty() || !fruit.shape.t.allFinite() ||
      ((fruit.shape.t.array() + reach) < view.lo.array()).any() || ((fruit.shape.t.array() - reach) > view.hi.array()).any())
    return false;
  int near = 0;
  for (const auto& p : view.points) {
    if ((p - fruit.shape.t).squaredNorm() > reach * reach) continue;
    const double d = fruit.shape.radialDistance(p);
    if (std::isfinite(d) && std::abs(d) <= 0.01 && ++near >= 3) return true;
  }
  return false;
}

void FruitSightingLog::record(const View& view, int fruit_id, FruitSightings* s) {
  std::uint64_t& last = last_pose_[fruit_id];
  if (last != view.pose) ++s->views;  // views of one pose are consecutive
  last = view.pose;
  if (!(s->first_seen <= view.time)) s->first_seen = view.time;  // NaN compares false
  if (!(s->last_seen >= view.time)) s->last_seen = view.time;
}

void FruitSightingLog::update(const std::vector<FruitEstimate>& fruits) {
  for (const auto& f : fruits) {
    if (!f.accepted) continue;
    auto it = sightings_.find(f.id);
    if (it == sightings_.end()) {  // new: the views that found it may already be matched
      it = sightings_.emplace(f.id, FruitSightings()).first;
      for (const auto& v : kept_)
        if (saw(v, f)) record(v, f.id, &it->second);
    }
    for (const auto& v : pending_)
      if (saw(v, f)) record(v, f.id, &it->second);
  }
  for (auto& v : pending_) kept_.push_back(std::move(v));
  pending_.clear();
  while (kept_.size() > kept_views_) kept_.pop_front();
}

void FruitSightingLog::clear() {
  pending_.clear();
  kept_.clear();
  sightings_.clear();
  last_pose_.clear();
  pose_ = 0;
}

}  // namespace fruit_shape_completion
