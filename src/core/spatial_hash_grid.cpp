#include <fruit_shape_completion/spatial_hash_grid.h>

#include <algorithm>

namespace fruit_shape_completion {

SpatialHashGrid::SpatialHashGrid(const PointList& points, double cell_size)
    : cell_(cell_size), inv_cell_(1.0 / cell_size), cells_(points.size() / 4 + 1) {
  // Sort point indices by cell key, then record each cell's range: one allocation for all cells.
  std::vector<std::pair<std::uint64_t, int>> keyed;
  keyed.reserve(points.size());
  for (int i = 0; i < static_cast<int>(points.size()); ++i) {
    const Point& p = points[i];
    if (!p.allFinite()) continue;
    keyed.emplace_back(packKey(cellOf(p.x()), cellOf(p.y()), cellOf(p.z())), i);
  }
  std::sort(keyed.begin(), keyed.end());
  sorted_.resize(keyed.size());
  index_.resize(keyed.size());
  for (size_t i = 0; i < keyed.size();) {
    size_t j = i;
    for (; j < keyed.size() && keyed[j].first == keyed[i].first; ++j) {
      index_[j] = keyed[j].second;
      sorted_[j] = points[keyed[j].second];
    }
    *cells_.insert(keyed[i].first).first = std::make_pair(static_cast<int>(i), static_cast<int>(j));
    const Point& p = sorted_[i];
    cell_list_.push_back({cellOf(p.x()), cellOf(p.y()), cellOf(p.z()), static_cast<int>(i), static_cast<int>(j)});
    i = j;
  }
}

void SpatialHashGrid::radiusSearch(const Point& p, double radius, std::vector<int>& out) const {
  out.clear();
  visitWithin(p, radius, [&out](const Point&, int idx) {
    out.push_back(idx);
    return true;
  });
}

bool SpatialHashGrid::anyWithin(const Point& p, double radius) const {
  return !visitWithin(p, radius, [](const Point&, int) { return false; });
}

}  // namespace fruit_shape_completion
