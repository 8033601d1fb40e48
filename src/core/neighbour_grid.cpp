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
  for (std::size_t k = 0; k < keyed.size(); ++k) {
    if (k == 0 || keyed[k].first != keyed[k - 1].first)
      cells_.emplace(keyed[k].first, std::make_pair(static_cast<int>(k), static_cast<int>(k)));
    order_.push_back(keyed[k].second);
    ++cells_[keyed[k].first].second;
  }
  cell_list_.reserve(cells_.size());
  for (std::size_t k = 0; k < keyed.size(); ++k)
    if (k == 0 || keyed[k].first != keyed[k - 1].first)
      cell_list_.emplace_back(cellOf(points[static_cast<std::size_t>(keyed[k].second)], inv_cell_), cells_[keyed[k].first]);
}

}  // namespace fruit_shape_completion
