#include <fruit_shape_completion/euclidean_clustering.h>
#include <fruit_shape_completion/neighbour_grid.h>

#include <algorithm>
#include <numeric>

namespace fruit_shape_completion {

// The clusters of pcl::EuclideanClusterExtraction (connected components of the "closer than
// tolerance" graph), found by union-find over a NeighbourGrid (docs/benchmarks.md).
std::vector<std::vector<int>> euclideanClusters(const PointList& points, const ClusteringParams& params) {
  std::vector<std::vector<int>> clusters;
  if (points.empty() || !(params.tolerance > 0.0)) return clusters;
  std::vector<int> parent(points.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](int i) {
    while (parent[static_cast<std::size_t>(i)] != i) i = parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    return i;
  };
  const NeighbourGrid grid(points, params.tolerance);
  grid.forEachPoint(params.tolerance, [&](int i, auto&& within) {
    within([&](int j, double, const Point&) {
      if (j <= i) return;
      const int a = root(i), b = root(j);
      if (a != b) parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
    });
  });
  // Components in the order of their first point; each root is its component's smallest index.
  std::vector<int> slot(points.size(), -1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) continue;
    const auto r = static_cast<std::size_t>(root(static_cast<int>(i)));
    if (slot[r] < 0) {
      slot[r] = static_cast<int>(clusters.size());
      clusters.emplace_back();
    }
    clusters[static_cast<std::size_t>(slot[r])].push_back(static_cast<int>(i));
  }
  clusters.erase(std::remove_if(clusters.begin(), clusters.end(),
                                [&](const std::vector<int>& c) {
                                  const int size = static_cast<int>(c.size());
                                  return size < params.min_size || size > params.max_size;
                                }),
                 clusters.end());
  // Largest first; equal sizes in the order of their first point.
  std::stable_sort(clusters.begin(), clusters.end(), [](const auto& l, const auto& r) { return l.size() > r.size(); });
  return clusters;
}

}  // namespace fruit_shape_completion
