#pragma once
// A uniform grid over a point list for fixed-radius neighbour queries. Kept beside PCL's
// kd-tree because the fruit surface is dense and the radii are a few voxels: a query reads the
// few cells around it, several times faster than a kd-tree radius search
// (docs/benchmarks.md), and clustering, normals and the outlier statistic run after every view.
#include <fruit_shape_completion/grid_cell.h>
#include <fruit_shape_completion/types.h>

#include <unordered_map>
#include <utility>
#include <vector>

namespace fruit_shape_completion {

class NeighbourGrid {
 public:
  // Over the finite points of `points` (not copied: they must outlive the grid).
  NeighbourGrid(const PointList& points, double cell_size);

  // fn(i, within) for every finite point i, cell by cell; within(visit) calls visit(j, squared
  // distance) for each point j within `radius` (<= the cell size) of point i, i included. The
  // neighbour cells are looked up once per cell, not once per point.
  template <typename Fn>
  void forEachPoint(double radius, Fn&& fn) const {
    const double r2 = radius * radius;
    std::vector<std::pair<int, int>> ranges;
    for (const auto& cell : cell_list_) {
      ranges.clear();
      for (std::int64_t dx = -1; dx <= 1; ++dx)
        for (std::int64_t dy = -1; dy <= 1; ++dy)
          for (std::int64_t dz = -1; dz <= 1; ++dz) {
            const auto it = cells_.find(packCellKey(cell.first + GridCell(dx, dy, dz)));
            if (it != cells_.end()) ranges.push_back(it->second);
          }
      for (int k = cell.second.first; k < cell.second.second; ++k) {
        const int i = order_[static_cast<std::size_t>(k)];
        const Point& p = points_[static_cast<std::size_t>(i)];
        fn(i, [&](auto&& visit) {
          for (const auto& range : ranges)
            for (int m = range.first; m < range.second; ++m) {
              const int j = order_[static_cast<std::size_t>(m)];
              const double d2 = (points_[static_cast<std::size_t>(j)] - p).squaredNorm();
              if (d2 <= r2) visit(j, d2);
            }
        });
      }
    }
  }

 private:
  const PointList& points_;
  double inv_cell_;
  std::vector<int> order_;  // point indices grouped by cell
  std::unordered_map<std::uint64_t, std::pair<int, int>> cells_;  // cell key -> range of order_
  std::vector<std::pair<GridCell, std::pair<int, int>>> cell_list_;  // the same cells, in key order
};

}  // namespace fruit_shape_completion
