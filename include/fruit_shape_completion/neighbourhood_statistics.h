#pragma once
// One pass over the fixed-radius neighbourhoods of a point cloud that gives, per point, the
// statistical outlier filter's statistic (mean distance to the k nearest neighbours) and a
// surface normal (PCA of the neighbourhood). The TSDF integrator runs it over each view's
// voxel-merged end points, where one neighbour search serves both.
#include <fruit_shape_completion/types.h>

#include <vector>

namespace fruit_shape_completion {

class SpatialHashGrid;

struct NeighbourhoodQuery {
  double radius = 0.01;  // neighbours are the points within this distance [m]
  int k = 10;            // for the mean k-NN distance; 0: not wanted
  bool normals = true;
  int threads = 1;       // the cloud is split by grid cells over this many threads
};

// knn (if k > 0) and normals (if wanted) get one entry per point:
// - knn[i]: mean distance from point i to its k nearest other points within the radius (as
//   meanKnnDistance), or the radius if it has fewer than k there;
// - normals[i]: unit surface normal (either sign), NaN where the neighbourhood holds fewer than
//   5 points (the point included) or does not span a surface (its second eigenvalue under
//   5 % of the largest: a line).
// Non-finite points get NaN for both (the outlier flags then mark them, as
// findStatisticalOutliers does). Distances are taken in float relative to nearby
// points: the statistic matches a double computation to ~1e-6 relative.
// `grid`, if given, is where the pass builds its spatial grid: a caller that keeps it between
// calls saves the page faults of fresh memory.
void analyseNeighbourhoods(const PointList& points, const NeighbourhoodQuery& query, std::vector<double>* knn,
                           std::vector<Eigen::Vector3d>* normals, SpatialHashGrid* grid = nullptr);

}  // namespace fruit_shape_completion
