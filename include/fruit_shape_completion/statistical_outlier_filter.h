#pragma once
// Statistical outlier removal (as PCL's StatisticalOutlierRemoval): a point whose mean distance
// to its k nearest neighbours exceeds the cloud's mean of that value by more than std_mul
// standard deviations is an outlier. Neighbours are looked for within search_radius (a
// NeighbourGrid, docs/benchmarks.md); a point with fewer than k there counts as having mean
// distance search_radius.
#include <fruit_shape_completion/types.h>

#include <vector>

namespace fruit_shape_completion {

struct OutlierFilterParams {
  int k = 10;
  double std_mul = 2.0;
  double search_radius = 0.01;  // [m]
  void validate() const;  // throws std::invalid_argument
};

// One flag per point: true for outliers (and for non-finite points).
std::vector<char> findStatisticalOutliers(const PointList& points, const OutlierFilterParams& params);

// The two steps, for a caller that gathers neighbourhoods itself (the TSDF integrator's one
// pass for outliers and normals):
// the statistic of one point from the squared distances `d2` to its neighbours within
// search_radius, itself excluded (reordered in place);
double meanNeighbourDistance(std::vector<double>* d2, const OutlierFilterParams& params);
// the flags from all statistics (NaN: a point that has none, flagged).
std::vector<char> flagOutliers(const std::vector<double>& statistic, const OutlierFilterParams& params);

}  // namespace fruit_shape_completion
