#pragma once
// roi_viewpoint_planner's automatic mode, as its default configuration samples and scores views
// (Planner.cfg: ROI contours + contour exploration, ROI_VICINITY_UTILITY, 100 samples each),
// written against the stand-in's ROI octree. docs/upstream_planner.md maps each function to the
// upstream one it emulates and says what differs.
#include <fruit_shape_completion/instrument/planner/roi_octree.h>
#include <fruit_shape_completion/shape_targets.h>
#include <fruit_shape_completion/instrument/sim/scene.h>

#include <octomap/OcTreeKey.h>

#include <random>
#include <unordered_map>
#include <vector>

namespace fruit_shape_completion {
namespace planner {

struct UpstreamSamplingParams {
  int roi_samples = 100, expl_samples = 100;  // roi_max_samples, expl_max_samples
  double min_range = 0.3, max_range = 0.5;    // sensor_min_range, sensor_max_range [m]
  double inflation_resolution = 0.05, inflation_radius = 0.3;  // computeInflatedRois(0.05, 0.3)
  double travel_weight = 0.2;   // utility = gain - travel_weight * distance from the camera
  double roi_threshold = 0.2;   // ROI candidates are used when the best scores above this
};

// octomap_vpp's InflatedRoiOcTree as ROI_VICINITY_UTILITY reads it: per cell of
// `resolution`, 1 at an ROI cell, falling linearly to 0 at `radius` along 26-neighbour steps.
class InflatedRois {
 public:
  InflatedRois(const RoiOcTree& tree, const std::vector<octomap::OcTreeKey>& roi_keys, double resolution,
               double radius);
  // 0 for cells the inflation did not reach (upstream: no node in the inflated tree).
  float value(const octomap::point3d& p) const;
  std::size_t cells() const { return values_.size(); }

 private:
  octomap::OcTreeKey key(const octomap::point3d& p) const;
  double resolution_;
  std::unordered_map<octomap::OcTreeKey, float, octomap::OcTreeKey::KeyHash> values_;
};

// A sampled view: the camera at `origin` looking along `direction` at `target`.
struct SampledView {
  Eigen::Vector3d origin, target, direction;
  double gain = 0.0, distance = 0.0, utility = 0.0;
  double shape_gain = 0.0;    // the predicted surface it would see (shape_view_gain.h), in utility
  bool shape_target = false;  // its target came from the estimators' extra targets
};

// RoiOcTree::getRoiKeys: the voxels whose ROI log-odds is positive (a pruned leaf: each of its voxels).
std::vector<octomap::OcTreeKey> upstreamRoiKeys(const RoiOcTree& tree);
// RoiContourSampler's pool: free 6-neighbours of ROI cells that have an unknown 6-neighbour.
PointList roiContourPool(const RoiOcTree& tree, const std::vector<octomap::OcTreeKey>& roi_keys);
// ContourSampler's pool: free leaves in the sampling region (the workspace) with both an unknown
// and an occupied 6-neighbour.
std::vector<octomap::OcTreeKey> contourKeys(const RoiOcTree& tree, const sim::Workspace& sampling_region);
// ViewpointPlanner::computeSurfaceNormalDir: minus the sum of the occupied 18-neighbours'
// offsets, normalised (zero if they cancel).
Eigen::Vector3d surfaceNormalDir(const RoiOcTree& tree, const octomap::OcTreeKey& key);
// RoiVicinityUtility::computeRoiWeightedIG on the ray origin -> target: each unknown cell before
// the first occupied one weighs 0.5 + 0.5 x its inflated ROI value; the sum over the ray's cells
// divided by their count.
double roiWeightedGain(const RoiOcTree& tree, const InflatedRois& inflated, const Eigen::Vector3d& origin,
                       const Eigen::Vector3d& target);

// One planning round's candidates, as ViewpointPlanner::plannerLoopOnce gets them.
struct SampledCandidates {
  std::vector<SampledView> roi, exploration;  // each sorted best first
  bool use_roi = false;                       // the ROI list's best scores above roi_threshold
  std::size_t roi_pool = 0, contour_pool = 0, inflated_cells = 0;
  const std::vector<SampledView>& chosen() const { return use_roi ? roi : exploration; }
};

// RoiContourSampler over the pool plus `extra` (the integration patch's shape targets; a
// sphere point on the side away from a target's direction is mirrored to the side it faces, and
// the predicted surface a view sees adds to its utility, as the patch does) and ContourSampler,
// both scored by ROI_VICINITY_UTILITY from `camera`;
// samples whose origin is outside the workspace are dropped, as upstream drops those outside
// its workspace tree.
SampledCandidates sampleUpstream(const RoiOcTree& tree, const sim::Workspace& workspace,
                                 const ShapeTargets& extra, const Eigen::Vector3d& camera,
                                 const UpstreamSamplingParams& params, std::mt19937& rng);

// dirVecToQuat: the camera rotation closest to `current` whose view axis (camera z) is `dir`.
Eigen::Matrix3d turnTowards(const Eigen::Matrix3d& current, const Eigen::Vector3d& dir);

}  // namespace planner
}  // namespace fruit_shape_completion
