#pragma once
// A uniform grid over a point list for fixed-radius neighbour queries. Kept beside PCL's
// kd-tree because the fruit surface is dense and the radii are a few voxels: a query reads the
// few cells around it, several times faster than a kd-tree radius search
// (docs/benchmarks.md), and clustering, normals, the outlier statistic and the missing surface
// run after every view.
#include <fruit_shape_completion/grid_cell.h>
#include <fruit_shape_completion/types.h>

#include <array>
#include <unordered_map>
#include <utility>
#include <vector>

namespace fruit_shape_completion {

class NeighbourGrid {
 public:
  // Over the finite points of `points` (copied in cell order, so a cell's points are adjacent
  // in memory).
  NeighbourGrid(const PointList& points, double cell_size);

  // fn(i, within) for every finite point i, cell by cell; within(visit) calls visit(j, squared
  // distance, point j) for each point j within `radius` (<= the cell size) of point i, i
  // included. The neighbour cells are looked up once per cell, not once per point.
  template <typename Fn>
  void forEachPoint(double radius, Fn&& fn) const {
    const double r2 = radius * radius;
    Ranges ranges;
    Hits hits;
    for (const auto& cell : cell_list_) {
      const int n = neighbourRanges(cell.first, &ranges);
      hits.makeRoom(0, ranges, n);
      for (int k = cell.second.first; k < cell.second.second; ++k) {
        const Point& p = sorted_[static_cast<std::size_t>(k)];
        fn(order_[static_cast<std::size_t>(k)], [&](auto&& visit) {
          hits.count = 0;
          for (int r = 0; r < n; ++r) collectWithin(p, ranges[r].first, ranges[r].second, r2, &hits);
          for (std::size_t h = 0; h < hits.count; ++h) {
            const auto m = static_cast<std::size_t>(hits.index[h]);
            visit(order_[m], hits.d2[h], sorted_[m]);
          }
        });
      }
    }
  }

  // fn(i, j, squared distance) once for every unordered pair of distinct finite points within
  // `radius` (<= the cell size): half the distance tests of forEachPoint, for symmetric
  // relations (clustering, neighbour statistics).
  template <typename Fn>
  void forEachPair(double radius, Fn&& fn) const {
    forEachPairByPosition(radius, [&](int k, int m, double d2) {
      fn(order_[static_cast<std::size_t>(k)], order_[static_cast<std::size_t>(m)], d2);
    });
  }
  // The same with the points' positions in the grid's cell order (pointAt, indexAt): a caller
  // that keeps per-point state in that order touches memory close together.
  template <typename Fn>
  void forEachPairByPosition(double radius, Fn&& fn) const {
    const double r2 = radius * radius;
    Ranges ranges;
    Hits hits;
    for (const auto& cell : cell_list_) {
      const int n = forwardRanges(cell.first, &ranges);
      hits.makeRoom(static_cast<std::size_t>(cell.second.second - cell.second.first), ranges, n);
      for (int k = cell.second.first; k < cell.second.second; ++k) {
        const Point& p = sorted_[static_cast<std::size_t>(k)];
        hits.count = 0;
        collectWithin(p, k + 1, cell.second.second, r2, &hits);
        for (int r = 0; r < n; ++r) collectWithin(p, ranges[r].first, ranges[r].second, r2, &hits);
        for (std::size_t h = 0; h < hits.count; ++h) fn(k, hits.index[h], hits.d2[h]);
      }
    }
  }
  std::size_t size() const { return sorted_.size(); }
  // The most points any one cell holds.
  std::size_t largestCell() const { return largest_cell_; }
  // How many points share a point's cell, on average over the points (itself included): a
  // query's candidates per cell it reads.
  double meanCellmates() const {
    return sorted_.empty() ? 0.0 : cell_mates_ / static_cast<double>(sorted_.size());
  }
  const Point& pointAt(std::size_t position) const { return sorted_[position]; }
  int indexAt(std::size_t position) const { return order_[position]; }

  // True if a point of the grid lies within `radius` (<= the cell size) of q.
  bool anyWithin(const Point& q, double radius) const;
  // visit(j, squared distance, point j) for each point j within `radius` (<= the cell size) of q.
  template <typename Visit>
  void forEachWithin(const Point& q, double radius, Visit&& visit) const {
    if (!q.allFinite()) return;
    const double r2 = radius * radius;
    Ranges ranges;
    const int n = neighbourRanges(cellOf(q, inv_cell_), &ranges);
    for (int r = 0; r < n; ++r)
      for (int m = ranges[r].first; m < ranges[r].second; ++m) {
        const Point& p = sorted_[static_cast<std::size_t>(m)];
        const double d2 = (p - q).squaredNorm();
        if (d2 <= r2) visit(order_[static_cast<std::size_t>(m)], d2, p);
      }
  }

 private:
  using Ranges = std::array<std::pair<int, int>, 27>;
  // The positions and squared distances of the candidates a point's loop found within the
  // radius, measured first and visited after.
  struct Hits {
    std::vector<int> index;
    std::vector<double> d2;
    std::size_t count = 0;
    // Room for `own` candidates plus those of the first n ranges.
    void makeRoom(std::size_t own, const Ranges& ranges, int n) {
      for (int r = 0; r < n; ++r) own += static_cast<std::size_t>(ranges[r].second - ranges[r].first);
      if (index.size() < own) {
        index.resize(own);
        d2.resize(own);
      }
    }
  };
  // Appends the candidates at positions [begin, end) within r2 of p to `hits` without a branch
  // per candidate: whether one lies within the radius is a coin toss a branch predictor loses.
  void collectWithin(const Point& p, int begin, int end, double r2, Hits* hits) const {
    for (int m = begin; m < end; ++m) {
      const double d2 = (sorted_[static_cast<std::size_t>(m)] - p).squaredNorm();
      hits->index[hits->count] = m;
      hits->d2[hits->count] = d2;
      hits->count += d2 <= r2 ? 1 : 0;
    }
  }
  // The ranges of the occupied cells among `cell` and its 26 neighbours; returns their count.
  int neighbourRanges(const GridCell& cell, Ranges* ranges) const;
  // The same for the 13 neighbours that come after `cell` (offsets lexicographically above
  // zero): each pair of neighbouring cells is seen from one side only.
  int forwardRanges(const GridCell& cell, Ranges* ranges) const;

  double inv_cell_;
  std::size_t largest_cell_ = 0;
  double cell_mates_ = 0.0;  // sum over cells of their points squared
  std::vector<int> order_;  // point indices grouped by cell
  PointList sorted_;        // the points in that order
  std::unordered_map<std::uint64_t, std::pair<int, int>> cells_;  // cell key -> range of order_
  std::vector<std::pair<GridCell, std::pair<int, int>>> cell_list_;  // the same cells, in key order
};

}  // namespace fruit_shape_completion
