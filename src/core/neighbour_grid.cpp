#include <fruit_shape_completion/neighbour_grid.h>

#include <algorithm>

namespace fruit_shape_completion {

NeighbourGrid::NeighbourGrid(const PointList& points, double cell_size) : points_(points), inv_cell_(1.0 / cell_size) {
  std::vector<std::pair<std::uint64_t, int>> keyed;
  keyed.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    if (points[i].allFinite()) keyed.emplace_back(packCellKey(cellOf(points[i], inv_cell_)), static_cast<int>(i));
  std::sort(keyed.begin(), keyed.end());
  order_.reserve(keyed.size());
  cells_.reserve(keyed.size() / 4 + 1);
  for (std::size_t begin = 0, end = 0; begin < keyed.size(); begin = end) {
    while (end < keyed.size() && keyed[end].first == keyed[begin].first) order_.push_back(keyed[end++].second);
    const std::pair<int, int> range(static_cast<int>(begin), static_cast<int>(end));
    cells_.emplace(keyed[begin].first, range);
    cell_list_.emplace_back(cellOf(points[static_cast<std::size_t>(keyed[begin].second)], inv_cell_), range);
  }
}

}  // namespace fruit_shape_completion
