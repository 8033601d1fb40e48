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
  // Bounded: its neighbour tests grow with the square of the radius over the voxel or pixel
  // spacing, on every view.
  if (!(search_radius > 0.0 && search_radius <= kMaxSearchRadius))
    throw std::invalid_argument("outlier filter search_radius must be in (0, 0.05] m");
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

namespace {

std::vector<char> outliersPointByPoint(const PointList& points, const NeighbourGrid& grid,
                                       const OutlierFilterParams& params) {
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

// Identical points are one point seen several times: its copies are its nearest neighbours at
// distance 0. Each position is searched once, so a driver's repeated point (or pixels without
// depth written as the origin) costs what one point does, not the square of their number; the
// statistic is the same as point by point.
std::vector<char> outliersByPosition(const PointList& points, const OutlierFilterParams& params) {
  std::vector<std::size_t> order;
  order.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    if (points[i].allFinite()) order.push_back(i);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const Point &p = points[a], &q = points[b];
    return p.x() != q.x() ? p.x() < q.x() : p.y() != q.y() ? p.y() < q.y() : p.z() < q.z();
  });
  PointList unique;
  std::vector<std::size_t> copies;
  std::vector<std::size_t> unique_of(points.size(), 0);
  for (std::size_t k = 0; k < order.size(); ++k) {
    if (k == 0 || points[order[k]] != points[order[k - 1]]) {
      unique.push_back(points[order[k]]);
      copies.push_back(0);
    }
    ++copies.back();
    unique_of[order[k]] = unique.size() - 1;
  }
  const auto k_max = static_cast<std::size_t>(params.k);
  NearestDistances nearest(unique.size(), params);
  for (std::size_t u = 0; u < unique.size(); ++u)
    for (std::size_t c = 1; c < std::min(copies[u], k_max + 1); ++c) nearest.add(u, 0.0);
  const NeighbourGrid grid(unique, params.search_radius);
  grid.forEachPair(params.search_radius, [&](int i, int j, double dd) {
    const auto a = static_cast<std::size_t>(i), b = static_cast<std::size_t>(j);
    for (std::size_t c = 0; c < std::min(copies[b], k_max); ++c) nearest.add(a, dd);
    for (std::size_t c = 0; c < std::min(copies[a], k_max); ++c) nearest.add(b, dd);
  });
  std::vector<double> statistic(points.size(), std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i : order) statistic[i] = nearest.meanDistance(unique_of[i]);
  return flagOutliers(statistic, params);
}

}  // namespace

std::vector<char> findStatisticalOutliers(const PointList& points, const OutlierFilterParams& params) {
  // A camera's fruit points fill a search-radius cell with a few hundred at most; a cell holding
  // thousands is where repeated points make the pair search quadratic, and only then are the
  // copies merged first (that costs a sort of the whole cloud).
  constexpr std::size_t kCrowdedCell = 2048;
  const NeighbourGrid grid(points, params.search_radius);
  if (grid.largestCell() <= kCrowdedCell) return outliersPointByPoint(points, grid, params);
  return outliersByPosition(points, params);
}

}  // namespace fruit_shape_completion
