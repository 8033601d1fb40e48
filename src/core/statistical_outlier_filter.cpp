#include <fruit_shape_completion/neighbour_grid.h>
#include <fruit_shape_completion/statistical_outlier_filter.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace fruit_shape_completion {

void OutlierFilterParams::validate() const {
  if (k < 1) throw std::invalid_argument("outlier filter k must be >= 1");
  if (!(std_mul > 0.0) || !std::isfinite(std_mul))
    throw std::invalid_argument("outlier filter std_mul must be a finite value > 0");
  if (!(search_radius > 0.0) || !std::isfinite(search_radius))
    throw std::invalid_argument("outlier filter search_radius must be a finite value > 0");
}

double meanNeighbourDistance(std::vector<double>* d2, const OutlierFilterParams& params) {
  const std::size_t k = static_cast<std::size_t>(params.k);
  if (d2->size() < k) return params.search_radius;
  std::nth_element(d2->begin(), d2->begin() + static_cast<long>(k - 1), d2->end());
  double m = 0.0;
  for (std::size_t j = 0; j < k; ++j) m += std::sqrt((*d2)[j]);
  return m / static_cast<double>(k);
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
  std::vector<double> statistic(points.size(), std::numeric_limits<double>::quiet_NaN()), d2;
  grid.forEachPoint(params.search_radius, [&](int i, auto&& within) {
    d2.clear();
    within([&](int j, double dd, const Point&) {
      if (j != i) d2.push_back(dd);
    });
    statistic[static_cast<std::size_t>(i)] = meanNeighbourDistance(&d2, params);
  });
  return flagOutliers(statistic, params);
}

}  // namespace fruit_shape_completion
