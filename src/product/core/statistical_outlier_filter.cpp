#include <fruit_shape_completion/neighbour_grid.h>
#include <fruit_shape_completion/statistical_outlier_filter.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace fruit_shape_completion {

void OutlierFilterParams::validate() const {
  // Bounded: the filter keeps k distances per point (a million points at k = 1000 is 4 GB).
  if (k < 1 || k > 1000) throw std::invalid_argument("outlier filter k must be in [1, 1000]");
  if (!(std_mul > 0.0) || !std::isfinite(std_mul))
    throw std::invalid_argument("outlier filter std_mul must be a finite value > 0");
  if (!(search_radius > 0.0) || !std::isfinite(search_radius))
    throw std::invalid_argument("outlier filter search_radius must be a finite value > 0");
}

NearestDistances::NearestDistances(std::size_t points, const OutlierFilterParams& params)
    : k_(static_cast<std::size_t>(params.k)),
      search_radius_(params.search_radius),
      d2_(points * k_, std::numeric_limits<float>::infinity()),
      count_(points, 0) {}

double NearestDistances::meanDistance(std::size_t i) const {
  if (count_[i] < k_) return search_radius_;
  double m = 0.0;
  for (std::size_t j = 0; j < k_; ++j) m += std::sqrt(d2_[i * k_ + j]);
  return m / static_cast<double>(k_);
}

std::vector<char> flagOutliers(const std::vector<double>& statistic, const OutlierFilterParams& params) {
  std::vector<char> outlier(statistic.size(), 1);
  double sum = 0.0, sum2 = 0.0;
  std::size_t n = 0;
  for (double m : statistic)
    if (!std::isnan(m)) {
      sum += m;
      sum2 += m * m;
      ++n;
    }
  if (n < 2) return outlier;
  // As PCL: the sample standard deviation.
  const double mean = sum / static_cast<double>(n);
  const double var = std::max(0.0, (sum2 - static_cast<double>(n) * mean * mean) / static_cast<double>(n - 1));
  const double threshold = mean + params.std_mul * std::sqrt(var);
  for (std::size_t i = 0; i < statistic.size(); ++i)
    if (!std::isnan(statistic[i])) outlier[i] = statistic[i] > threshold;
  return outlier;
}

std::vector<char> findStatisticalOutliers(const PointList& points, const OutlierFilterParams& params) {
  const NeighbourGrid grid(points, params.search_radius);
  NearestDistances nearest(points.size(), params);
  grid.forEachPair(params.search_radius, [&](int i, int j, double dd) {
    nearest.add(static_cast<std::size_t>(i), dd);
    nearest.add(static_cast<std::size_t>(j), dd);
  });
  std::vector<double> statistic(points.size(), std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 0; i < points.size(); ++i)
    if (points[i].allFinite()) statistic[i] = nearest.meanDistance(i);
  return flagOutliers(statistic, params);
}

}  // namespace fruit_shape_completion
