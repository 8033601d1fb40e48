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
  // Over the finite points of `points` (not copied: they must outlive the grid). A query
  // radius up to `cell_size` looks at 27 cells at most.
  NeighbourGrid(const PointList& points, double cell_size);

  // visit(index, squared distance) for each point within `radius` of p.
  template <typename Visit>
  void forEachWithin(const Point& p, double radius, Visit&& visit) const {
    const GridCell lo = cellOf(p - Point::Constant(radius), inv_cell_);
    const GridCell hi = cellOf(p + Point::Constant(radius), inv_cell_);
    const double r2 = radius * radius;
    for (auto x = lo.x(); x <= hi.x(); ++x)
      for (auto y = lo.y(); y <= hi.y(); ++y)
        for (auto z = lo.z(); z <= hi.z(); ++z) {
          const auto it = cells_.find(packCellKey(GridCell(x, y, z)));
          if (it == cells_.end()) continue;
          for (int k = it->second.first; k < it->second.second; ++k) {
            const int i = order_[static_cast<std::size_t>(k)];
            const double d2 = (points_[static_cast<std::size_t>(i)] - p).squaredNorm();
            if (d2 <= r2) visit(i, d2);
          }
        }
  }

 private:
  const PointList& points_;
  double inv_cell_;
  std::vector<int> order_;  // point indices grouped by cell
  std::unordered_map<std::uint64_t, std::pair<int, int>> cells_;  // cell key -> range of order_
};

}  // namespace fruit_shape_completion
