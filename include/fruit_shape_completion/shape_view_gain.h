#pragma once
// How much predicted, unseen fruit surface a view would see: a term for the planner's utility,
// after NBV-SC (Menon et al., IROS 2023), which scores views by the predicted surface they see.
// Upstream's ROI_VICINITY_UTILITY follows one ray to one target; this counts every shape target
// in the view's cone that faces the camera and whose line of sight the planner's map leaves clear.
#include <fruit_shape_completion/shape_targets.h>

#include <octomap/OcTreeKey.h>
#include <octomap/octomap_types.h>

#include <functional>

namespace fruit_shape_completion {

// True if the planner's map blocks the line from `from` to `to` (an occupied cell on it).
using RayBlocked = std::function<bool(const Eigen::Vector3d& from, const Eigen::Vector3d& to)>;

// The summed gains of the targets a camera at `origin` looking along `view_dir` would see:
// inside the targets' view cone and range, on surface facing the camera (where a target has a
// direction) and, with `blocked`, not hidden. At most `max_rays` lines are traced, spread evenly
// over the candidates; the others count at the traced ones' clear share. 0 without gains.
double shapeViewGain(const ShapeTargets& targets, const Eigen::Vector3d& origin, const Eigen::Vector3d& view_dir,
                     const RayBlocked& blocked = nullptr, int max_rays = 32);

// An Eigen point as OctoMap's single-precision point (the planner's octree speaks octomap).
inline octomap::point3d toOctomapPoint(const Eigen::Vector3d& v) {
  return octomap::point3d(static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z()));
}

// Lines of sight through an octomap occupancy tree (the planner's map; the caller holds its
// lock): blocked by any occupied cell on the line, or where the line leaves the tree.
template <typename OccupancyTree>
RayBlocked occupiedCellsBlock(const OccupancyTree& tree) {
  return [&tree](const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
    octomap::KeyRay ray;
    if (!tree.computeRayKeys(toOctomapPoint(from), toOctomapPoint(to), ray)) return true;
    for (const auto& k : ray) {
      const auto* n = tree.search(k);
      if (n != nullptr && tree.isNodeOccupied(n)) return true;
    }
    return false;
  };
}

}  // namespace fruit_shape_completion
