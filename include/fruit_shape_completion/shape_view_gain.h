#pragma once
// How much predicted, unseen fruit surface a view would see: a term for the planner's utility,
// after NBV-SC (Menon et al., IROS 2023), which scores views by the predicted surface they see.
// Upstream's ROI_VICINITY_UTILITY follows one ray to one target; this counts every shape target
// in the view's cone that faces the camera and whose line of sight the planner's map leaves clear.
#include <fruit_shape_completion/shape_targets.h>

#include <octomap/OcTreeKey.h>
#include <octomap/octomap_types.h>

#include <cmath>
#include <functional>

namespace fruit_shape_completion {

// True if the planner's map blocks the line from `from` to `to` (an occupied cell on it).
using RayBlocked = std::function<bool(const Eigen::Vector3d& from, const Eigen::Vector3d& to)>;

// True if the planner's map holds an occupied cell within `radius` of `at`.
using OccupiedNear = std::function<bool(const Eigen::Vector3d& at, double radius)>;

// The summed gains of the targets a camera at `origin` looking along `view_dir` would see:
// inside the targets' view cone and range, on surface facing the camera (where a target has a
// direction) and, with `blocked`, not hidden. At most `max_rays` lines are traced, spread evenly
// over the candidates; the others count at the traced ones' clear share. 0 without gains, and 0
// where `occupied_near` finds the map's plant within the targets' view_clearance of `origin`.
double shapeViewGain(const ShapeTargets& targets, const Eigen::Vector3d& origin, const Eigen::Vector3d& view_dir,
                     const RayBlocked& blocked = nullptr, const OccupiedNear& occupied_near = nullptr,
                     int max_rays = 32);

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

// Occupied cells of an octomap occupancy tree near a point (the caller holds its lock): any
// occupied leaf, of whatever size, whose box comes within the radius. Near the edge of the
// tree's range (or at a non-finite point) it answers true, as a line leaving the tree is blocked.
template <typename OccupancyTree>
OccupiedNear occupiedCellsNear(const OccupancyTree& tree) {
  return [&tree](const Eigen::Vector3d& at, double radius) {
    if (!at.allFinite() || !std::isfinite(radius)) return true;
    if (radius < 0.0) return false;
    const Eigen::Vector3d r = Eigen::Vector3d::Constant(radius);
    octomap::OcTreeKey lo, hi;
    if (!tree.coordToKeyChecked(toOctomapPoint(at - r), lo) || !tree.coordToKeyChecked(toOctomapPoint(at + r), hi))
      return true;
    for (auto it = tree.begin_leafs_bbx(lo, hi), end = tree.end_leafs_bbx(); it != end; ++it) {
      if (!tree.isNodeOccupied(*it)) continue;
      const octomap::point3d c = it.getCoordinate();
      const Eigen::Vector3d centre(c.x(), c.y(), c.z());
      const Eigen::Vector3d half = Eigen::Vector3d::Constant(0.5 * it.getSize());
      if ((at.cwiseMax(centre - half).cwiseMin(centre + half) - at).norm() <= radius) return true;
    }
    return false;
  };
}

}  // namespace fruit_shape_completion
