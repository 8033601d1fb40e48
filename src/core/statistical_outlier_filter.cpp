#include <fruit_shape_completion/spatial_hash_grid.h>
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

double meanKnnDistance(std::vector<double>& d2, int k, double fallback) {
  if (d2.size() < static_cast<std::size_t>(k)) return fallback;
  std::nth_element(d2.begin(), d2.begin() + (k - 1), d2.end());
  double m = 0.0;
  for (int j = 0; j < k; ++j) m += std::sqrt(d2[j]);
  return m / k;
}

std::vector<char> flagStatisticalOutliers(const std::vector<double>& mean_knn_distance, double std_mul) {
  std::vector<char> outlier(mean_knn_distance.size(), 1);
  double sum = 0.0, sum2 = 0.0;
  std::size_t n = 0;
  for (double m : mean_knn_distance)
    if (std::isfinite(m)) {
      sum += m;
      sum2 += m * m;
      ++n;
    }
  if (n == 0) return outlier;
  const double mean = sum / n;
  const double threshold = mean + std_mul * std::sqrt(std::max(0.0, sum2 / n - mean * mean));
  for (std::size_t i = 0; i < mean_knn_distance.size(); ++i)
    outlier[i] = !(mean_knn_distance[i] <= threshold);
  return outlier;
}

std::vector<char> findStatisticalOutliers(const PointList& points, const OutlierFilterParams& params) {
  const SpatialHashGrid grid(points, params.search_radius);
  std::vector<double> mean_dist(points.size(), std::numeric_limits<double>::quiet_NaN());
  std::vector<double> d2;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) continue;
    d2.clear();
    grid.visitWithin(points[i], params.search_radius, [&](const Point& q, int j) {
      if (static_cast<std::size_t>(j) != i) d2.push_back((q - points[i]).squaredNorm());
      return true;
    });
    mean_dist[i] = meanKnnDistance(d2, params.k, params.search_radius);
  }
  return flagStatisticalOutliers(mean_dist, params.std_mul);
}

}  // namespace fruit_shape_completion
