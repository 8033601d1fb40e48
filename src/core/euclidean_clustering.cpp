#include <fruit_shape_completion/euclidean_clustering.h>
#include <fruit_shape_completion/spatial_hash_grid.h>

#include <algorithm>

namespace fruit_shape_completion {

std::vector<std::vector<int>> euclideanClusters(const PointList& points,
                                                const ClusteringParams& params) {
  std::vector<std::vector<int>> clusters;
  if (points.empty() || !(params.tolerance > 0.0)) return clusters;
  const SpatialHashGrid grid(points, params.tolerance);
  std::vector<char> visited(points.size(), 0);
  std::vector<int> queue, neighbours;
  for (size_t seed = 0; seed < points.size(); ++seed) {
    if (visited[seed] || !points[seed].allFinite()) continue;
    queue.assign(1, static_cast<int>(seed));
    visited[seed] = 1;
    for (size_t head = 0; head < queue.size(); ++head) {
      grid.radiusSearch(points[queue[head]], params.tolerance, neighbours);
      for (int n : neighbours) {
        if (visited[n]) continue;
        visited[n] = 1;
        queue.push_back(n);
      }
    }
    const int size = static_cast<int>(queue.size());
    if (size < params.min_size || size > params.max_size) continue;
    std::sort(queue.begin(), queue.end());
    clusters.push_back(queue);
  }
  std::stable_sort(clusters.begin(), clusters.end(),
                   [](const auto& l, const auto& r) { return l.size() > r.size(); });
  return clusters;
}

}  // namespace fruit_shape_completion
