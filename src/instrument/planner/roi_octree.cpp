#include <fruit_shape_completion/instrument/planner/roi_octree.h>

#include <algorithm>
#include <unordered_map>
#include <unordered_set>

namespace fruit_shape_completion {
namespace planner {

std::istream& RoiOcTreeNode::readData(std::istream& s) {
  s.read(reinterpret_cast<char*>(&value), sizeof(value));
  s.read(reinterpret_cast<char*>(&roi_), sizeof(roi_));
  return s;
}

std::ostream& RoiOcTreeNode::writeData(std::ostream& s) const {
  s.write(reinterpret_cast<const char*>(&value), sizeof(value));
  s.write(reinterpret_cast<const char*>(&roi_), sizeof(roi_));
  return s;
}

RoiOcTree::RoiOcTree(double resolution) : octomap::OccupancyOcTreeBase<RoiOcTreeNode>(resolution) {}

Eigen::Vector3d RoiOcTree::center(const octomap::OcTreeKey& k) const {
  const octomap::point3d p = keyToCoord(k);
  return Eigen::Vector3d(p.x(), p.y(), p.z());
}

octomap::OcTreeKey RoiOcTree::key(const Eigen::Vector3d& p) const {
  return coordToKey(octomap::point3d(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())));
}

std::size_t RoiOcTree::insertRoiCloud(const PointList& points, const std::vector<std::int32_t>& roi_indices,
                                      const Eigen::Vector3d& origin) {
  if (!origin.allFinite()) return 0;
  std::vector<char> in_roi(points.size(), 0);
  for (const auto i : roi_indices)
    if (i >= 0 && static_cast<std::size_t>(i) < points.size()) in_roi[static_cast<std::size_t>(i)] = 1;
  octomap::Pointcloud cloud;
  cloud.reserve(points.size());
  using KeySet = std::unordered_set<octomap::OcTreeKey, octomap::OcTreeKey::KeyHash>;
  KeySet region, off_region;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Point& p = points[i];
    if (!p.allFinite()) continue;
    const octomap::point3d q(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
    cloud.push_back(q);
    octomap::OcTreeKey k;
    if (coordToKeyChecked(q, k)) (in_roi[i] ? region : off_region).insert(k);
  }
  insertPointCloud(cloud, octomap::point3d(origin.x(), origin.y(), origin.z()), -1.0, false, false);
  auto update = [&](const octomap::OcTreeKey& k, float step) {
    RoiOcTreeNode* n = search(k);
    if (n == nullptr) return;
    // search() may return a pruned inner node standing for many voxels; setting the same value
    // again expands it down to the single voxel (lazy: no re-pruning), so only that voxel's ROI
    // changes.
    n = setNodeValue(k, n->getLogOdds(), true);
    if (n == nullptr) return;
    n->setRoiLogOdds(std::min(roi_max, std::max(roi_min, n->roiLogOdds() + step)));
  };
  for (const auto& k : region) update(k, roi_hit);
  for (const auto& k : off_region)
    if (region.count(k) == 0) update(k, roi_miss);  // ROI points' voxels have priority
  return cloud.size();
}

std::vector<octomap::OcTreeKey> RoiOcTree::voxelKeys(const leaf_iterator& leaf) const {
  if (leaf.getDepth() == getTreeDepth()) return {leaf.getKey()};
  const int side = 1 << (getTreeDepth() - leaf.getDepth());
  const octomap::OcTreeKey base =
      coordToKey(leaf.getCoordinate() - octomap::point3d(1, 1, 1) * (0.5 * leaf.getSize() - 0.5 * resolution));
  std::vector<octomap::OcTreeKey> keys;
  keys.reserve(static_cast<std::size_t>(side) * side * side);
  for (int x = 0; x < side; ++x)
    for (int y = 0; y < side; ++y)
      for (int z = 0; z < side; ++z) keys.emplace_back(base[0] + x, base[1] + y, base[2] + z);
  return keys;
}

std::vector<RoiCluster> RoiOcTree::roiClusters(int min_voxels) const {
  std::unordered_set<octomap::OcTreeKey, octomap::OcTreeKey::KeyHash> roi;
  for (auto it = begin_leafs(), end = end_leafs(); it != end; ++it)
    if (isRoi(&*it))
      for (const auto& k : voxelKeys(it)) roi.insert(k);
  std::vector<RoiCluster> clusters;
  std::unordered_set<octomap::OcTreeKey, octomap::OcTreeKey::KeyHash> seen;
  for (const auto& start : roi) {
    if (seen.count(start)) continue;
    RoiCluster c;
    std::vector<octomap::OcTreeKey> queue{start};
    seen.insert(start);
    for (std::size_t h = 0; h < queue.size(); ++h) {
      const octomap::OcTreeKey k = queue[h];
      c.keys.push_back(k);
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            const octomap::OcTreeKey n(k[0] + dx, k[1] + dy, k[2] + dz);
            if (roi.count(n) && seen.insert(n).second) queue.push_back(n);
          }
    }
    if (static_cast<int>(c.keys.size()) < min_voxels) continue;
    c.box_min = Eigen::Vector3d::Constant(1e9);
    c.box_max = Eigen::Vector3d::Constant(-1e9);
    for (const auto& k : c.keys) {
      const Eigen::Vector3d p = center(k);
      c.box_min = c.box_min.cwiseMin(p);
      c.box_max = c.box_max.cwiseMax(p);
    }
    clusters.push_back(std::move(c));
  }
  return clusters;
}

PointList RoiOcTree::roiContourTargets() const {
  PointList targets;
  std::unordered_set<octomap::OcTreeKey, octomap::OcTreeKey::KeyHash> added;
  for (auto it = begin_leafs(getTreeDepth()), end = end_leafs(); it != end; ++it) {
    if (!isRoi(&*it) || it.getDepth() != getTreeDepth()) continue;
    const octomap::OcTreeKey k = it.getKey();
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const octomap::OcTreeKey n(k[0] + dx, k[1] + dy, k[2] + dz);
          const RoiOcTreeNode* nn = search(n);
          if (nn == nullptr || isNodeOccupied(nn) || added.count(n)) continue;  // want known free cells
          bool unknown_near = false;
          for (int ex = -1; ex <= 1 && !unknown_near; ++ex)
            for (int ey = -1; ey <= 1 && !unknown_near; ++ey)
              for (int ez = -1; ez <= 1 && !unknown_near; ++ez)
                unknown_near = search(octomap::OcTreeKey(n[0] + ex, n[1] + ey, n[2] + ez)) == nullptr;
          if (unknown_near) {
            added.insert(n);
            targets.push_back(center(n));
          }
        }
  }
  return targets;
}

}  // namespace planner
}  // namespace fruit_shape_completion
