#pragma once
// Statistical outlier removal (as PCL's StatisticalOutlierRemoval): a point whose mean distance
// to its k nearest neighbours exceeds the cloud's mean of that value by more than std_mul
// standard deviations is an outlier. Neighbours are searched within `search_radius`; a point
// with fewer than k neighbours there counts as having mean distance search_radius.
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

// The statistics step alone, for callers that gather the neighbourhoods themselves: flags the
// values above mean + std_mul * standard deviation.
std::vector<char> flagStatisticalOutliers(const std::vector<double>& mean_knn_distance, double std_mul);

// Mean distance to the k nearest of the given squared neighbour distances (`d2` is reordered),
// or `fallback` if there are fewer than k.
double meanKnnDistance(std::vector<double>& d2, int k, double fallback);

}  // namespace fruit_shape_completion
