#pragma once
// A uniform hash grid over a point list for fixed-radius neighbour queries. With the cell size
// equal to the query radius a query looks up the (at most 27) cells its box overlaps; cheaper
// to build than a k-d tree and exact for the radius searches of clustering, normals and the
// missing-surface test. Points are stored cell by cell, so a query reads contiguous memory.
// For a neighbourhood pass over all points, forEachCell() shares the 27 lookups among all
// points of a cell.
#include <fruit_shape_completion/flat_hash_map.h>
#include <fruit_shape_completion/types.h>

#include <cmath>
#include <cstdint>
#include <vector>

namespace fruit_shape_completion {

class SpatialHashGrid {
 public:
  // Builds the grid over the finite points of `points` (copied).
  SpatialHashGrid(const PointList& points, double cell_size);

  // Indices (into the original list) of the points within `radius` of `p`.
  void radiusSearch(const Point& p, double radius, std::vector<int>& out) const;
  // True if any point lies within `radius` of `p`.
  bool anyWithin(const Point& p, double radius) const;
  // Calls visit(point, index) for each point within `radius` of `p` until it returns false;
  // returns false if stopped early.
  template <typename Visit>
  bool visitWithin(const Point& p, double radius, Visit&& visit) const;

  double cellSize() const { return cell_; }

  // The occupied cells in grid order; cell c holds the stored points [begin, end).
  struct Cell {
    std::int64_t x, y, z;
    int begin, end;
  };
  const std::vector<Cell>& cells() const { return cell_list_; }
  // Stored point k (points are stored cell by cell) and its index in the original list.
  const Point& storedPoint(int k) const { return sorted_[k]; }
  int originalIndex(int k) const { return index_[k]; }
  // Calls visit(cell, ranges, n) for cells [first, last) of cells(), with the [begin, end)
  // ranges of the n occupied cells among it and its 26 neighbours. Every point within the
  // cell size of a point of the cell lies in those ranges.
  template <typename Visit>
  void forEachCell(std::size_t first, std::size_t last, Visit&& visit) const;

  static std::uint64_t packKey(std::int64_t x, std::int64_t y, std::int64_t z) {
    // 21 bits per axis: +-1 million cells, i.e. +-10 km at 1 cm.
    const std::uint64_t mask = (1ull << 21) - 1;
    return ((static_cast<std::uint64_t>(x) & mask) << 42) |
           ((static_cast<std::uint64_t>(y) & mask) << 21) | (static_cast<std::uint64_t>(z) & mask);
  }

 private:
  std::int64_t cellOf(double v) const { return static_cast<std::int64_t>(std::floor(v * inv_cell_)); }
  double cell_;
  double inv_cell_;
  // Cell key -> [begin, end) range into sorted_ / index_.
  FlatHashMap<std::pair<int, int>> cells_;
  PointList sorted_;         // points grouped by cell
  std::vector<int> index_;   // original index of each sorted point
  std::vector<Cell> cell_list_;
};

template <typename Visit>
void SpatialHashGrid::forEachCell(std::size_t first, std::size_t last, Visit&& visit) const {
  // near[column][dz + 1]: the range of cell (x + dx, y + dy, z + dz), column = 3 (dx + 1) + dy + 1;
  // {0, 0} when empty. Cells come in key order, so the next cell is often the one above in z:
  // its 27 neighbours then share 18 with this one's and only 9 are looked up.
  std::pair<int, int> near[9][3];
  auto lookup = [this](std::int64_t x, std::int64_t y, std::int64_t z) {
    const std::pair<int, int>* r = cells_.find(packKey(x, y, z));
    return r != nullptr ? *r : std::make_pair(0, 0);
  };
  std::pair<int, int> ranges[27];
  const Cell* prev = nullptr;
  for (std::size_t c = first; c < last && c < cell_list_.size(); ++c) {
    const Cell& cell = cell_list_[c];
    const bool above = prev != nullptr && prev->x == cell.x && prev->y == cell.y && prev->z + 1 == cell.z;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy) {
        std::pair<int, int>* col = near[3 * (dx + 1) + dy + 1];
        if (above) {
          col[0] = col[1];
          col[1] = col[2];
          col[2] = lookup(cell.x + dx, cell.y + dy, cell.z + 1);
        } else {
          for (int dz = -1; dz <= 1; ++dz) col[dz + 1] = lookup(cell.x + dx, cell.y + dy, cell.z + dz);
        }
      }
    int n = 0;
    for (const auto& col : near)
      for (const auto& r : col)
        if (r.second > r.first) ranges[n++] = r;
    visit(cell, ranges, n);
    prev = &cell;
  }
}

template <typename Visit>
bool SpatialHashGrid::visitWithin(const Point& p, double radius, Visit&& visit) const {
  const Eigen::Vector3d lo = ((p.array() - radius) * inv_cell_).floor();
  const Eigen::Vector3d hi = ((p.array() + radius) * inv_cell_).floor();
  if (!lo.allFinite() || !hi.allFinite()) return true;
  const double r2 = radius * radius;
  for (auto x = static_cast<std::int64_t>(lo.x()); x <= static_cast<std::int64_t>(hi.x()); ++x)
    for (auto y = static_cast<std::int64_t>(lo.y()); y <= static_cast<std::int64_t>(hi.y()); ++y)
      for (auto z = static_cast<std::int64_t>(lo.z()); z <= static_cast<std::int64_t>(hi.z()); ++z) {
        const std::pair<int, int>* range = cells_.find(packKey(x, y, z));
        if (range == nullptr) continue;
        for (int k = range->first; k < range->second; ++k)
          if ((sorted_[k] - p).squaredNorm() <= r2 && !visit(sorted_[k], index_[k])) return false;
      }
  return true;
}

}  // namespace fruit_shape_completion
