#include "view_gain.h"

#include <octomap/octomap_types.h>

namespace fruit_shape_completion {
namespace planner {

namespace {

std::uint64_t coarseKey(const RoiOcTree& tree, const Eigen::Vector3d& p) {
  const octomap::OcTreeKey k = tree.key(p);
  return (static_cast<std::uint64_t>(k[0] >> 2) << 32) | (static_cast<std::uint64_t>(k[1] >> 2) << 16) | (k[2] >> 2);
}

}  // namespace

// 4 cm cells around the targets: unknown space there is worth seeing.
KeySet interestCells(const RoiOcTree& tree, const PointList& targets) {
  KeySet cells;
  const double s = 4 * tree.getResolution();
  for (const auto& t : targets)
    for (int x = -1; x <= 1; ++x)
      for (int y = -1; y <= 1; ++y)
        for (int z = -1; z <= 1; ++z) cells.insert(coarseKey(tree, t + s * Eigen::Vector3d(x, y, z)));
  return cells;
}

// Unknown octree cells seen along a grid of camera rays (stopping at occupied cells); only
// those in `interest` count unless interest is null.
double viewGain(const RoiOcTree& tree, const PinholeCamera& cam, const PlannerParams& p, const KeySet* interest) {
  double gain = 0.0;
  octomap::KeyRay ray;
  const octomap::point3d o(cam.position.x(), cam.position.y(), cam.position.z());
  for (int j = 0; j < p.utility_rays_y; ++j)
    for (int i = 0; i < p.utility_rays_x; ++i) {
      const int u = static_cast<int>((i + 0.5) * cam.width / p.utility_rays_x);
      const int v = static_cast<int>((j + 0.5) * cam.height / p.utility_rays_y);
      const Eigen::Vector3d end = cam.position + p.utility_range * cam.rayDirection(u, v);
      if (!tree.computeRayKeys(o, octomap::point3d(end.x(), end.y(), end.z()), ray)) continue;
      for (const auto& k : ray) {
        const RoiOcTreeNode* n = tree.search(k);
        if (n != nullptr) {
          if (tree.isNodeOccupied(n)) break;
          continue;
        }
        if (interest == nullptr || interest->count(coarseKey(tree, tree.center(k)))) gain += 1.0;
      }
    }
  return gain;
}

}  // namespace planner
}  // namespace fruit_shape_completion
