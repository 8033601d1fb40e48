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

// The connected components left out for their size.
struct ClustersLeftOut {
  int oversized = 0;          // above max_size: a dense cloud, or fruits and leaves grown into one
  int undersized = 0;         // below min_size: specks, or a fruit seen through a small gap
  int undersized_points = 0;  // their points

  // Whether a component of `size` points is a cluster under `params`; if not, it is counted here.
  bool admits(int size, const ClusteringParams& params) {
    oversized += size > params.max_size;
    undersized += size < params.min_size;
    undersized_points += size < params.min_size ? size : 0;
    return size >= params.min_size && size <= params.max_size;
  }
};

// Non-finite points are ignored. Clusters are sorted by size, largest first; each cluster's
// indices are ascending. `left_out`, if given, gets the components dropped for their size.
std::vector<std::vector<int>> euclideanClusters(const PointList& points, const ClusteringParams& params,
                                                ClustersLeftOut* left_out = nullptr);

}  // namespace fruit_shape_completion
