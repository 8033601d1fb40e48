#include <fruit_shape_completion/instrument/planner/upstream_sampling.h>
#include <fruit_shape_completion/shape_view_gain.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <queue>
#include <unordered_set>

namespace fruit_shape_completion {
namespace planner {

namespace {

using KeySet = std::unordered_set<octomap::OcTreeKey, octomap::OcTreeKey::KeyHash>;

Eigen::Vector3d toEigen(const octomap::point3d& p) { return Eigen::Vector3d(p.x(), p.y(), p.z()); }

octomap::OcTreeKey offset(const octomap::OcTreeKey& k, int dx, int dy, int dz) {
  return octomap::OcTreeKey(static_cast<octomap::key_type>(k[0] + dx), static_cast<octomap::key_type>(k[1] + dy),
                            static_cast<octomap::key_type>(k[2] + dz));
}

// octomap_vpp's NodeState for the occupancy: unknown (no node, or log-odds 0), free (< 0), occupied (> 0).
int occupancyState(const RoiOcTreeNode* n) {
  if (n == nullptr || n->getLogOdds() == 0.0f) return 0;
  return n->getLogOdds() < 0.0f ? -1 : 1;
}

constexpr int kNb6[6][3] = {{-1, 0, 0}, {0, -1, 0}, {0, 0, -1}, {0, 0, 1}, {0, 1, 0}, {1, 0, 0}};

bool hasUnknownAndOccupiedNeighbour6(const RoiOcTree& tree, const octomap::OcTreeKey& key) {
  bool unknown = false, occupied = false;
  for (int i = 0; i < 6 && !(unknown && occupied); ++i) {
    const int s = occupancyState(tree.search(offset(key, kNb6[i][0], kNb6[i][1], kNb6[i][2])));
    unknown = unknown || s == 0;
    occupied = occupied || s == 1;
  }
  return unknown && occupied;
}

double sensorDistance(const UpstreamSamplingParams& p, std::mt19937& rng) {
  if (p.min_range == p.max_range) return p.max_range;
  return std::uniform_real_distribution<double>(p.min_range, p.max_range)(rng);
}

// sampleRandomPointOnSphere: a normally distributed direction scaled to `radius`.
Eigen::Vector3d pointOnSphere(const Eigen::Vector3d& center, double radius, std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::Vector3d d;
  for (int i = 0; i < 3; ++i) d[i] = g(rng);  // one draw after the other: a defined order
  return center + radius * d.normalized();
}

void sortBestFirst(std::vector<SampledView>* views) {
  std::stable_sort(views->begin(), views->end(),
                   [](const SampledView& a, const SampledView& b) { return a.utility > b.utility; });
}

}  // namespace

InflatedRois::InflatedRois(const RoiOcTree& tree, const std::vector<octomap::OcTreeKey>& roi_keys, double resolution,
                           double radius)
    : resolution_(resolution) {
  // RoiOcTree::computeInflatedRois, full construction: ROI cells start at the maximum value 1;
  // the highest open cell is fixed next and offers each 26-neighbour its value less one step per
  // unit of offset length.
  const float max_val = 1.0f;
  const float step = static_cast<float>(max_val / radius * resolution);
  struct Open {
    float value;
    octomap::OcTreeKey key;
    bool operator<(const Open& o) const { return value < o.value; }
  };
  std::priority_queue<Open> open;
  std::unordered_map<octomap::OcTreeKey, float, octomap::OcTreeKey::KeyHash> offered;
  for (const auto& k : roi_keys) {
    const octomap::OcTreeKey ik = key(tree.keyToCoord(k));
    if (offered.emplace(ik, max_val).second) open.push({max_val, ik});
  }
  while (!open.empty()) {
    const Open top = open.top();
    open.pop();
    if (values_.count(top.key) || top.value < offered[top.key]) continue;  // done, or a stale offer
    values_[top.key] = top.value;
    for (int i = -1; i <= 1; ++i)
      for (int j = -1; j <= 1; ++j)
        for (int k = -1; k <= 1; ++k) {
          const int diff = std::abs(i) + std::abs(j) + std::abs(k);
          if (diff == 0) continue;
          const float v = static_cast<float>(top.value - step * std::sqrt(static_cast<double>(diff)));
          if (v <= 0.0f) continue;
          const octomap::OcTreeKey n = offset(top.key, i, j, k);
          if (values_.count(n)) continue;
          auto it = offered.find(n);
          if (it != offered.end() && it->second >= v) continue;
          offered[n] = v;
          open.push({v, n});
        }
  }
}

octomap::OcTreeKey InflatedRois::key(const octomap::point3d& p) const {
  // OcTreeBaseImpl::coordToKey at this tree's resolution (depth 16).
  auto c = [&](float x) { return static_cast<octomap::key_type>(static_cast<int>(std::floor(x / resolution_)) + 32768); };
  return octomap::OcTreeKey(c(p.x()), c(p.y()), c(p.z()));
}

float InflatedRois::value(const octomap::point3d& p) const {
  const auto it = values_.find(key(p));
  return it == values_.end() ? 0.0f : it->second;
}

std::vector<octomap::OcTreeKey> upstreamRoiKeys(const RoiOcTree& tree) {
  std::vector<octomap::OcTreeKey> keys;
  // A pruned leaf (a solid block whose voxels are all alike) stands for all its voxels; upstream
  // keeps their keys in its ROI key set however the tree prunes.
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
    if (it->roiLogOdds() > 0.0f) {
      const std::vector<octomap::OcTreeKey> voxels = tree.voxelKeys(it);
      keys.insert(keys.end(), voxels.begin(), voxels.end());
    }
  return keys;
}

PointList roiContourPool(const RoiOcTree& tree, const std::vector<octomap::OcTreeKey>& roi_keys) {
  KeySet free_neighbours;
  for (const auto& k : roi_keys)
    for (const auto& o : kNb6) {
      const octomap::OcTreeKey n = offset(k, o[0], o[1], o[2]);
      if (occupancyState(tree.search(n)) == -1) free_neighbours.insert(n);
    }
  PointList pool;
  for (const auto& k : free_neighbours)
    for (const auto& o : kNb6)
      if (occupancyState(tree.search(offset(k, o[0], o[1], o[2]))) == 0) {
        pool.push_back(tree.center(k));
        break;
      }
  // KeySet order is the hash table's; sort so that a seed gives the same draws everywhere.
  std::sort(pool.begin(), pool.end(), [](const Point& a, const Point& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  });
  return pool;
}

std::vector<octomap::OcTreeKey> contourKeys(const RoiOcTree& tree, const sim::Workspace& region) {
  std::vector<octomap::OcTreeKey> keys;
  for (auto it = tree.begin_leafs_bbx(toOctomapPoint(region.box_min), toOctomapPoint(region.box_max)),
            end = tree.end_leafs_bbx();
       it != end; ++it) {
    if (!region.contains(toEigen(it.getCoordinate()))) continue;
    if (it->getLogOdds() < 0.0f && hasUnknownAndOccupiedNeighbour6(tree, it.getKey())) keys.push_back(it.getKey());
  }
  return keys;
}

Eigen::Vector3d surfaceNormalDir(const RoiOcTree& tree, const octomap::OcTreeKey& key) {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (int i = -1; i <= 1; ++i)
    for (int j = -1; j <= 1; ++j)
      for (int k = -1; k <= 1; ++k) {
        const int diff = std::abs(i) + std::abs(j) + std::abs(k);
        if (diff == 0 || diff == 3) continue;  // the 18-neighbourhood
        if (occupancyState(tree.search(offset(key, i, j, k))) == 1) n -= Eigen::Vector3d(i, j, k);
      }
  const double len = n.norm();
  return len > 1e-9 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

double roiWeightedGain(const RoiOcTree& tree, const InflatedRois& inflated, const Eigen::Vector3d& origin,
                       const Eigen::Vector3d& target) {
  octomap::KeyRay ray;
  if (!tree.computeRayKeys(toOctomapPoint(origin), toOctomapPoint(target), ray) || ray.size() == 0) return 0.0;
  double sum = 0.0;
  for (const auto& k : ray) {
    const double weight = 0.5 + 0.5 * inflated.value(tree.keyToCoord(k));
    const RoiOcTreeNode* n = tree.search(k);
    if (n == nullptr) {
      sum += weight;
      continue;
    }
    const double occ = n->getOccupancy();
    if (occ > 0.6) break;  // the view is blocked
    if (occ > 0.4) sum += weight;
  }
  return sum / static_cast<double>(ray.size());
}

SampledCandidates sampleUpstream(const RoiOcTree& tree, const sim::Workspace& workspace,
                                 const ShapeTargets& extra, const Eigen::Vector3d& camera,
                                 const UpstreamSamplingParams& p, std::mt19937& rng) {
  SampledCandidates out;
  const std::vector<octomap::OcTreeKey> roi_keys = upstreamRoiKeys(tree);
  const InflatedRois inflated(tree, roi_keys, p.inflation_resolution, p.inflation_radius);
  out.inflated_cells = inflated.cells();
  auto score = [&](SampledView v) {
    v.gain = roiWeightedGain(tree, inflated, v.origin, v.target);
    v.distance = (v.origin - camera).norm();
    v.utility = v.gain - p.travel_weight * v.distance;
    return v;
  };

  const RayBlocked blocked = occupiedCellsBlock(tree);
  const OccupiedNear occupied_near = occupiedCellsNear(tree);
  // RoiContourSampler (with the integration patch's extra targets in its pool).
  PointList pool = roiContourPool(tree, roi_keys);
  const std::size_t contour_count = pool.size();
  pool.insert(pool.end(), extra.points.begin(), extra.points.end());
  out.roi_pool = pool.size();
  if (!pool.empty()) {
    std::uniform_int_distribution<std::size_t> pick(0, pool.size() - 1);
    for (int i = 0; i < p.roi_samples; ++i) {
      SampledView v;
      const std::size_t i_target = pick(rng);
      v.target = pool[i_target];
      v.shape_target = i_target >= contour_count;
      const double dist = sensorDistance(p, rng);
      v.origin = pointOnSphere(v.target, dist, rng);
      if (v.shape_target && i_target - contour_count < extra.directions.size() &&
          extra.directions[i_target - contour_count].dot(v.origin - v.target) < 0.0)
        v.origin = 2.0 * v.target - v.origin;
      v.direction = (v.target - v.origin).normalized();
      if (!workspace.contains(v.origin)) continue;
      v = score(v);
      // The integration patch: the predicted surface the view would see (0 without view gains,
      // 0 for a camera within the targets' clearance of an occupied cell).
      v.shape_gain = shapeViewGain(extra, v.origin, v.direction, blocked, occupied_near);
      v.utility += v.shape_gain;
      out.roi.push_back(v);
    }
  }

  // ContourSampler: the sampling region is the workspace (upstream's default without a sampling tree).
  const std::vector<octomap::OcTreeKey> contours = contourKeys(tree, workspace);
  out.contour_pool = contours.size();
  std::vector<octomap::OcTreeKey> selected;
  std::sample(contours.begin(), contours.end(), std::back_inserter(selected), static_cast<std::size_t>(p.expl_samples), rng);
  for (const auto& k : selected) {
    const Eigen::Vector3d normal = surfaceNormalDir(tree, k);
    const Eigen::Vector3d contour = tree.center(k);
    const double dist = sensorDistance(p, rng);
    if (normal.isZero()) continue;  // upstream: a NaN pose, outside any workspace
    SampledView v;
    v.origin = contour + dist * normal;
    v.target = contour;
    v.direction = -normal;
    if (!workspace.contains(v.origin)) continue;
    if (occupancyState(tree.search(toOctomapPoint(v.origin))) == 1) continue;
    out.exploration.push_back(score(v));
  }
  sortBestFirst(&out.roi);
  sortBestFirst(&out.exploration);
  out.use_roi = !out.roi.empty() && out.roi.front().utility > p.roi_threshold;
  return out;
}

Eigen::Matrix3d turnTowards(const Eigen::Matrix3d& current, const Eigen::Vector3d& dir) {
  const Eigen::Vector3d from = current.col(2);
  const Eigen::Vector3d to = dir.normalized();
  const Eigen::Vector3d axis = from.cross(to);
  const double angle = std::atan2(axis.norm(), from.dot(to));
  if (axis.norm() < 1e-12) {
    if (angle < 1e-6) return current;
    // Opposite: any half turn about an axis across the view; the camera's own x axis.
    return Eigen::AngleAxisd(M_PI, current.col(0)).toRotationMatrix() * current;
  }
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix() * current;
}

}  // namespace planner
}  // namespace fruit_shape_completion
