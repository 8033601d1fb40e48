#pragma once
// Splits a surface cloud into fruits: points closer than `tolerance` are connected; connected
// components with min_size..max_size points are clusters (the paper: 0.01 m, 100..10000).
#include <fruit_shape_completion/types.h>

#include <vector>

namespace fruit_shape_completion {

struct ClusteringParams {
  double tolerance = 0.01;
  int min_size = 100;
  int max_size = 10000;
};

// Non-finite points are ignored. Clusters are sorted by size, largest first; each cluster's
// indices are ascending. `oversized`, if given, gets the number of components above max_size
// (left out: a dense cloud, or fruits and leaves grown into one).
std::vector<std::vector<int>> euclideanClusters(const PointList& points,
                                                const ClusteringParams& params, int* oversized = nullptr);

}  // namespace fruit_shape_completion
