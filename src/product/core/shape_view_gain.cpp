#include <fruit_shape_completion/shape_view_gain.h>

#include <algorithm>
#include <vector>

namespace fruit_shape_completion {

double shapeViewGain(const ShapeTargets& targets, const Eigen::Vector3d& origin, const Eigen::Vector3d& view_dir,
                     const RayBlocked& blocked, const OccupiedNear& occupied_near, int max_rays) {
  const std::size_t n = targets.points.size();
  if (targets.gains.size() != n || n == 0 || !origin.allFinite() || !view_dir.allFinite()) return 0.0;
  const double len = view_dir.norm();
  if (len < 1e-12) return 0.0;
  const Eigen::Vector3d axis = view_dir / len;
  const bool directed = targets.directions.size() == n;
  std::vector<std::size_t> seen;
  double in_cone = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d d = targets.points[i] - origin;
    const double dist = d.norm();
    if (dist < 1e-9 || dist > targets.view_max_range) continue;
    if (axis.dot(d) < targets.view_cos_half_angle * dist) continue;
    if (directed && targets.directions[i].dot(d) > 0.0) continue;  // the surface faces away
    seen.push_back(i);
    in_cone += targets.gains[i];
  }
  if (seen.empty() || in_cone <= 0.0) return 0.0;
  if (occupied_near && targets.view_clearance > 0.0 && occupied_near(origin, targets.view_clearance)) return 0.0;
  if (!blocked) return in_cone;
  const std::size_t rays = std::min<std::size_t>(seen.size(), static_cast<std::size_t>(std::max(1, max_rays)));
  double traced = 0.0, clear = 0.0;
  for (std::size_t r = 0; r < rays; ++r) {
    const std::size_t i = seen[r * seen.size() / rays];
    traced += targets.gains[i];
    if (!blocked(origin, targets.points[i])) clear += targets.gains[i];
  }
  return traced > 0.0 ? in_cone * clear / traced : 0.0;
}

}  // namespace fruit_shape_completion
