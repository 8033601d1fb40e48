#pragma once
// The planner's map: an OctoMap occupancy octree whose nodes also carry an ROI (fruit)
// log-odds. Scans are inserted by ray casting (free along rays, occupied at end points); fruit
// end points raise the ROI value, other end points lower it. ROI clusters (26-neighbourhood)
// give the "Old" fruit estimate of the upstream planner: the axis-aligned box of each cluster.
#include <fruit_shape_completion/types.h>

#include <octomap/OccupancyOcTreeBase.h>
#include <octomap/OcTreeNode.h>

#include <cstdint>
#include <vector>

namespace fruit_shape_completion {
namespace planner {

class RoiOcTreeNode : public octomap::OcTreeNode {
 public:
  RoiOcTreeNode() = default;
  RoiOcTreeNode(const RoiOcTreeNode& rhs) : octomap::OcTreeNode(rhs), roi_(rhs.roi_) {}
  bool operator==(const RoiOcTreeNode& rhs) const { return rhs.value == value && rhs.roi_ == roi_; }
  void copyData(const RoiOcTreeNode& from) {
    octomap::OcTreeNode::copyData(from);
    roi_ = from.roi_;
  }
  float roiLogOdds() const { return roi_; }
  void setRoiLogOdds(float v) { roi_ = v; }
  std::istream& readData(std::istream& s);
  std::ostream& writeData(std::ostream& s) const;

 private:
  float roi_ = 0.0f;
};

struct RoiCluster {
  std::vector<octomap::OcTreeKey> keys;
  // Box of the voxel centres (not of the voxel extents, which would add a voxel per axis).
  Eigen::Vector3d box_min, box_max;
  Eigen::Vector3d center() const { return 0.5 * (box_min + box_max); }
  double volume() const { return (box_max - box_min).prod(); }
};

class RoiOcTree : public octomap::OccupancyOcTreeBase<RoiOcTreeNode> {
 public:
  explicit RoiOcTree(double resolution = 0.01);
  RoiOcTree* create() const override { return new RoiOcTree(resolution); }
  std::string getTreeType() const override { return "RoiOcTree"; }

  // ROI log-odds steps and clamp (hit: log-odds of 0.7).
  float roi_hit = 0.847f, roi_miss = -0.4f, roi_min = -2.0f, roi_max = 3.5f;
  float roi_threshold = 0.0f;  // ROI cells: occupied with ROI log-odds above this

  // registerPointcloudWithRoi's two calls on one PointcloudWithRoi (map frame): insertPointCloud
  // of every finite point from `origin` (no range limit, a ray per point, no pruning deferred),
  // then insertRegionScan: the voxels of the points `roi_indices` lists gain ROI, the voxels of
  // the other points, unless an ROI point's too, lose it. Non-finite points and indices outside
  // the cloud are skipped. Returns the number of points used.
  std::size_t insertRoiCloud(const PointList& points, const std::vector<std::int32_t>& roi_indices,
                             const Eigen::Vector3d& origin);

  // The full-depth voxels a leaf stands for: itself, or every voxel of a pruned leaf's cube.
  std::vector<octomap::OcTreeKey> voxelKeys(const leaf_iterator& leaf) const;

  bool isRoi(const RoiOcTreeNode* n) const { return n && isNodeOccupied(n) && n->roiLogOdds() > roi_threshold; }
  // Occupied ROI leaves at full depth, grouped by 26-connectivity; clusters smaller than
  // min_voxels are dropped.
  std::vector<RoiCluster> roiClusters(int min_voxels = 10) const;
  // Free cells next to ROI cells that still have unknown neighbours: where looking reveals fruit.
  PointList roiContourTargets() const;

  Eigen::Vector3d center(const octomap::OcTreeKey& k) const;
  octomap::OcTreeKey key(const Eigen::Vector3d& p) const;
};

}  // namespace planner
}  // namespace fruit_shape_completion
