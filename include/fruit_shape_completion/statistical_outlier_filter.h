#pragma once
// Statistical outlier removal (as PCL's StatisticalOutlierRemoval): a point whose mean distance
// to its k nearest neighbours exceeds the cloud's mean of that value by more than std_mul
// standard deviations is an outlier. Neighbours are looked for within search_radius (a
// NeighbourGrid, docs/benchmarks.md); a point with fewer than k there counts as having mean
// distance search_radius.
#include <fruit_shape_completion/types.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace fruit_shape_completion {

struct OutlierFilterParams {
  int k = 10;
  double std_mul = 2.0;
  double search_radius = 0.01;  // [m]
  static constexpr double kMaxSearchRadius = 0.05;
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
  // Keeps row i the k smallest so far, ascending (padded with +inf). Without branches: element
  // j becomes max(row[j-1], min(row[j], d2)), so the data-dependent exits of an insertion sort
  // cannot be mispredicted.
  void add(std::size_t i, double distance2) {
    const float d2 = static_cast<float>(distance2);
    float* row = &d2_[i * k_];
    for (std::size_t j = k_ - 1; j > 0; --j) row[j] = std::max(row[j - 1], std::min(row[j], d2));
    row[0] = std::min(row[0], d2);
    count_[i] = std::min<std::uint32_t>(count_[i] + 1, static_cast<std::uint32_t>(k_));
  }
  // The mean distance to the k nearest, or search_radius for a point with fewer than k.
  double meanDistance(std::size_t i) const;

 private:
  std::size_t k_;
  double search_radius_;
  std::vector<float> d2_;  // single precision: half the memory; a statistic needs no more
  std::vector<std::uint32_t> count_;
};
// the flags from all statistics (NaN: a point that has none, flagged).
std::vector<char> flagOutliers(const std::vector<double>& statistic, const OutlierFilterParams& params);

}  // namespace fruit_shape_completion
