#include <fruit_shape_completion/euclidean_clustering.h>
#include <fruit_shape_completion/neighbour_grid.h>

#include <algorithm>
#include <numeric>

namespace fruit_shape_completion {

// The clusters of pcl::EuclideanClusterExtraction (connected components of the "closer than
// tolerance" graph), found by union-find over a NeighbourGrid (docs/benchmarks.md).
//
// Points sharing a cube of side tolerance/8 first join one representative: dense or duplicate
// input then costs a sort, not a neighbour scan per point over the whole pile (100 k identical
// points took 17-54 s). A member lies within 0.22 tolerance of its representative, so a link
// between two dense piles may be judged off by that much; the TSDF surface (4 mm spacing, 1 cm
// tolerance) has one point per cube and is clustered exactly.
std::vector<std::vector<int>> euclideanClusters(const PointList& points, const ClusteringParams& params,
                                                ClustersLeftOut* left_out) {
  std::vector<std::vector<int>> clusters;
  if (left_out) *left_out = ClustersLeftOut();
  if (points.empty() || !(params.tolerance > 0.0)) return clusters;
  // Sorted by packed key, then by the cell itself: the key wraps every 2^21 cells (2.6 km at a
  // 1 cm tolerance), and points of two cells that share a key must not share a representative.
  struct Keyed {
    std::uint64_t key;
    GridCell cell;
    int index;
  };
  std::vector<Keyed> keyed;
  keyed.reserve(points.size());
  const double inv_cube = 8.0 / params.tolerance;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (points[i].allFinite()) {
      const GridCell cell = cellOf(points[i], inv_cube);
      keyed.push_back({packCellKey(cell), cell, static_cast<int>(i)});
    }
  std::sort(keyed.begin(), keyed.end(), [](const Keyed& a, const Keyed& b) {
    if (a.key != b.key) return a.key < b.key;
    if (a.cell != b.cell)
      return std::lexicographical_compare(a.cell.data(), a.cell.data() + 3, b.cell.data(), b.cell.data() + 3);
    return a.index < b.index;
  });
  PointList reps;
  std::vector<int> rep_of(points.size(), -1);
  for (std::size_t k = 0; k < keyed.size(); ++k) {
    if (k == 0 || keyed[k].key != keyed[k - 1].key || keyed[k].cell != keyed[k - 1].cell)
      reps.push_back(points[static_cast<std::size_t>(keyed[k].index)]);
    rep_of[static_cast<std::size_t>(keyed[k].index)] = static_cast<int>(reps.size()) - 1;
  }

  std::vector<int> parent(reps.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](int i) {
    while (parent[static_cast<std::size_t>(i)] != i) i = parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    return i;
  };
  const NeighbourGrid grid(reps, params.tolerance);
  grid.forEachPair(params.tolerance, [&](int i, int j, double) {
    const int a = root(i), b = root(j);
    if (a != b) parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
  });
  // Components in the order of their first point.
  std::vector<int> slot(reps.size(), -1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (rep_of[i] < 0) continue;  // not finite
    const auto r = static_cast<std::size_t>(root(rep_of[i]));
    if (slot[r] < 0) {
      slot[r] = static_cast<int>(clusters.size());
      clusters.emplace_back();
    }
    clusters[static_cast<std::size_t>(slot[r])].push_back(static_cast<int>(i));
  }
  ClustersLeftOut counted;
  clusters.erase(std::remove_if(clusters.begin(), clusters.end(),
                                [&](const std::vector<int>& c) {
                                  return !counted.admits(static_cast<int>(c.size()), params);
                                }),
                 clusters.end());
  if (left_out) *left_out = counted;
  // Largest first; equal sizes in the order of their first point.
  std::stable_sort(clusters.begin(), clusters.end(), [](const auto& l, const auto& r) { return l.size() > r.size(); });
  return clusters;
}

}  // namespace fruit_shape_completion
