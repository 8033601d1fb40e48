#pragma once
// A uniform hash grid over a point list for fixed-radius neighbour queries. With the cell size
// equal to the query radius a query looks up the (at most 27) cells its box overlaps; cheaper
// to build than a k-d tree and exact for the radius searches of clustering, normals and the
// missing-surface test. Points are stored cell by cell, so a query reads contiguous memory;
// the build sorts them by cell with a radix sort (a few linear passes, no hashing per point).
// For a neighbourhood pass over all points, forEachCell() hands each cell its neighbour cells
// found by walking the sorted cell list (no lookups), shared by all points of the cell.
#include <fruit_shape_completion/flat_hash_map.h>
#include <fruit_shape_completion/types.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace fruit_shape_completion {

class SpatialHashGrid {
 public:
  // Builds the grid over the finite points of `points` (copied).
  SpatialHashGrid(const PointList& points, double cell_size);
  SpatialHashGrid() = default;  // empty; build() fills it
  // (Re)builds the grid in place, reusing the memory of the last build: a full frame's grid
  // is ~20 MB, and fresh memory costs a page fault per 4 KiB.
  void build(const PointList& points, double cell_size);

  // Indices (into the original list) of the points within `radius` of `p`.
  void radiusSearch(const Point& p, double radius, std::vector<int>& out) const;
  // True if any point lies within `radius` of `p`.
  bool anyWithin(const Point& p, double radius) const;
  // Calls visit(point, index) for each point within `radius` of `p` until it returns false;
  // returns false if stopped early.
  template <typename Visit>
  bool visitWithin(const Point& p, double radius, Visit&& visit) const;

  double cellSize() const { return cell_; }

  // The occupied cells in (x, y, z) order; cell c holds the stored points [begin, end).
  struct Cell {
    std::int64_t x, y, z;
    int begin, end;
  };
  const std::vector<Cell>& cells() const { return cell_list_; }
  // Stored point k (points are stored cell by cell) and its index in the original list.
  const Point& storedPoint(int k) const { return sorted_[k]; }
  int originalIndex(int k) const { return index_[k]; }
  // Calls visit(cell, ranges, n) for cells [first, last) of cells(), with the n [begin, end)
  // ranges of stored points that make up the occupied cells among it and its 26 neighbours
  // (at most 9: a column's cells are consecutive). Every point within the cell size of a point
  // of the cell lies in those ranges.
  template <typename Visit>
  void forEachCell(std::size_t first, std::size_t last, Visit&& visit) const;

  static std::uint64_t packKey(std::int64_t x, std::int64_t y, std::int64_t z) {
    // 21 bits per axis: +-1 million cells, i.e. +-10 km at 1 cm.
    const std::uint64_t mask = (1ull << 21) - 1;
    return ((static_cast<std::uint64_t>(x) & mask) << 42) |
           ((static_cast<std::uint64_t>(y) & mask) << 21) | (static_cast<std::uint64_t>(z) & mask);
  }

 private:
  double cell_ = 1.0;
  double inv_cell_ = 1.0;
  // Cell key -> [begin, end) range into sorted_ / index_.
  FlatHashMap<std::pair<int, int>> cells_;
  PointList sorted_;         // points grouped by cell
  std::vector<int> index_;   // original index of each sorted point
  std::vector<Cell> cell_list_;
  // The radix sort's keys and buffers, kept for the next build().
  std::vector<std::uint64_t> key_, key_tmp_;
  std::vector<int> order_tmp_;
};

template <typename Visit>
void SpatialHashGrid::forEachCell(std::size_t first, std::size_t last, Visit&& visit) const {
  // Cells come in (x, y, z) order, so in each of the 9 neighbour columns (x + dx, y + dy) the
  // cells the next cell wants lie at or after those this one wanted: one cursor per column walks
  // the cell list forward, in memory order, instead of 9 to 27 hash lookups per cell.
  const std::size_t count = cell_list_.size();
  last = last < count ? last : count;
  if (first >= last) return;
  auto before = [](const Cell& c, std::int64_t x, std::int64_t y, std::int64_t z) {
    return c.x != x ? c.x < x : (c.y != y ? c.y < y : c.z < z);
  };
  std::size_t cursor[9];
  const Cell& start = cell_list_[first];
  for (int col = 0; col < 9; ++col) {
    const std::int64_t x = start.x + col / 3 - 1, y = start.y + col % 3 - 1, z = start.z - 1;
    cursor[col] = static_cast<std::size_t>(
        std::partition_point(cell_list_.begin(), cell_list_.end(), [&](const Cell& c) { return before(c, x, y, z); }) -
        cell_list_.begin());
  }
  std::pair<int, int> ranges[27];
  for (std::size_t c = first; c < last; ++c) {
    const Cell& cell = cell_list_[c];
    int n = 0;
    for (int col = 0; col < 9; ++col) {  // column (dx, dy) = (col / 3 - 1, col % 3 - 1), dz ascending
      const std::int64_t x = cell.x + col / 3 - 1, y = cell.y + col % 3 - 1, z = cell.z - 1;
      std::size_t k = cursor[col];
      while (k < count && before(cell_list_[k], x, y, z)) ++k;
      cursor[col] = k;
      for (; k < count; ++k) {
        const Cell& o = cell_list_[k];
        if (o.x != x || o.y != y || o.z > z + 2) break;
        // Cells next to each other in a column are next to each other in memory: one range.
        if (n > 0 && ranges[n - 1].second == o.begin)
          ranges[n - 1].second = o.end;
        else
          ranges[n++] = std::make_pair(o.begin, o.end);
      }
    }
    visit(cell, ranges, n);
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
