#pragma once
// A uniform hash grid over a point list for fixed-radius neighbour queries. With the cell size
// equal to the query radius a query visits the 8 cells its sphere overlaps; cheaper to build
// than a k-d tree and exact for the radius searches of clustering, normals and the
// missing-surface test. Points are stored cell by cell, so a query reads contiguous memory.
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

  static std::uint64_t packKey(std::int64_t x, std::int64_t y, std::int64_t z) {
    // 21 bits per axis: +-1 million cells, i.e. +-10 km at 1 cm.
    const std::uint64_t mask = (1ull << 21) - 1;
    return ((static_cast<std::uint64_t>(x) & mask) << 42) |
           ((static_cast<std::uint64_t>(y) & mask) << 21) | (static_cast<std::uint64_t>(z) & mask);
  }

 private:
  double cell_;
  double inv_cell_;
  // Cell key -> [begin, end) range into sorted_ / index_.
  FlatHashMap<std::pair<int, int>> cells_;
  PointList sorted_;         // points grouped by cell
  std::vector<int> index_;   // original index of each sorted point
};

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
