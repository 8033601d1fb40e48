#include <fruit_shape_completion/neighbour_grid.h>

#include <algorithm>

namespace fruit_shape_completion {

NeighbourGrid::NeighbourGrid(const PointList& points, double cell_size) : inv_cell_(1.0 / cell_size) {
  std::vector<std::pair<std::uint64_t, int>> keyed;
  keyed.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    if (points[i].allFinite()) keyed.emplace_back(packCellKey(cellOf(points[i], inv_cell_)), static_cast<int>(i));
  std::sort(keyed.begin(), keyed.end());
  order_.reserve(keyed.size());
  sorted_.reserve(keyed.size());
  cells_.reserve(keyed.size() / 4 + 1);
  for (std::size_t begin = 0, end = 0; begin < keyed.size(); begin = end) {
    while (end < keyed.size() && keyed[end].first == keyed[begin].first) {
      order_.push_back(keyed[end].second);
      sorted_.push_back(points[static_cast<std::size_t>(keyed[end++].second)]);
    }
    const std::pair<int, int> range(static_cast<int>(begin), static_cast<int>(end));
    largest_cell_ = std::max(largest_cell_, end - begin);
    cell_mates_ += static_cast<double>(end - begin) * static_cast<double>(end - begin);
    cells_.emplace(keyed[begin].first, range);
    cell_list_.emplace_back(cellOf(sorted_[begin], inv_cell_), range);
  }
}

int NeighbourGrid::neighbourRanges(const GridCell& cell, Ranges* ranges) const {
  int n = 0;
  for (std::int64_t dx = -1; dx <= 1; ++dx)
    for (std::int64_t dy = -1; dy <= 1; ++dy)
      for (std::int64_t dz = -1; dz <= 1; ++dz) {
        const auto it = cells_.find(packCellKey(cell + GridCell(dx, dy, dz)));
        if (it != cells_.end()) (*ranges)[static_cast<std::size_t>(n++)] = it->second;
      }
  return n;
}

int NeighbourGrid::forwardRanges(const GridCell& cell, Ranges* ranges) const {
  int n = 0;
  for (std::int64_t dx = 0; dx <= 1; ++dx)
    for (std::int64_t dy = dx == 0 ? 0 : -1; dy <= 1; ++dy)
      for (std::int64_t dz = (dx == 0 && dy == 0) ? 1 : -1; dz <= 1; ++dz) {
        const auto it = cells_.find(packCellKey(cell + GridCell(dx, dy, dz)));
        if (it != cells_.end()) (*ranges)[static_cast<std::size_t>(n++)] = it->second;
      }
  return n;
}

bool NeighbourGrid::anyWithin(const Point& q, double radius) const {
  if (!q.allFinite() || sorted_.empty()) return false;
  const double r2 = radius * radius;
  Ranges ranges;
  const int n = neighbourRanges(cellOf(q, inv_cell_), &ranges);
  for (int r = 0; r < n; ++r)
    for (int m = ranges[r].first; m < ranges[r].second; ++m)
      if ((sorted_[static_cast<std::size_t>(m)] - q).squaredNorm() <= r2) return true;
  return false;
}

}  // namespace fruit_shape_completion
