#pragma once
// Statistical outlier removal (as PCL's StatisticalOutlierRemoval): a point whose mean distance
// to its k nearest neighbours exceeds the cloud's mean of that value by more than std_mul
// standard deviations is an outlier. Neighbours are looked for within search_radius (a
// NeighbourGrid, docs/benchmarks.md); a point with fewer than k there counts as having mean
// distance search_radius.
#include <fruit_shape_completion/types.h>

#include <algorithm>
#include <cstddef>
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
// the k smallest squared distances of each point to its neighbours within search_radius, fed
// one close pair at a time (add() for both points of a pair), and the statistic from them;
class NearestDistances {
 public:
  NearestDistances(std::size_t points, const OutlierFilterParams& params);
  void add(std::size_t i, double d2) {  // keeps row i ascending, at most k long
    double* row = &d2_[i * k_];
    std::size_t n = count_[i];
    if (n == k_) {
      if (d2 >= row[k_ - 1]) return;
      --n;
    }
    while (n > 0 && row[n - 1] > d2) {
      row[n] = row[n - 1];
      --n;
    }
    row[n] = d2;
    count_[i] = std::min(count_[i] + 1, k_);
  }
  // The mean distance to the k nearest, or search_radius for a point with fewer than k.
  double meanDistance(std::size_t i) const;

 private:
  std::size_t k_;
  double search_radius_;
  std::vector<double> d2_;
  std::vector<std::size_t> count_;
};
// the flags from all statistics (NaN: a point that has none, flagged).
std::vector<char> flagOutliers(const std::vector<double>& statistic, const OutlierFilterParams& params);

}  // namespace fruit_shape_completion
