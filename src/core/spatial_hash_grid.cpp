#include <fruit_shape_completion/spatial_hash_grid.h>

#include <algorithm>

namespace fruit_shape_completion {

SpatialHashGrid::SpatialHashGrid(const PointList& points, double cell_size)
    : cell_(cell_size), inv_cell_(1.0 / cell_size), cells_(points.size() / 4 + 1) {
  // Counting sort: number the occupied cells as they first appear (cells_ maps key -> number
  // for now), sort only the distinct keys (a few points share each cell), then place every
  // point in its cell's range in index order: the layout a sort of all (key, index) pairs
  // would give, at a fraction of the cost.
  std::vector<int> cell_of(points.size(), -1);
  std::vector<std::uint64_t> keys;
  std::vector<int> counts;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Point& p = points[i];
    if (!p.allFinite()) continue;
    const std::uint64_t key = packKey(cellOf(p.x()), cellOf(p.y()), cellOf(p.z()));
    const auto ins = cells_.insert(key);
    if (ins.second) {
      ins.first->first = static_cast<int>(keys.size());
      keys.push_back(key);
      counts.push_back(0);
    }
    cell_of[i] = ins.first->first;
    ++counts[static_cast<std::size_t>(ins.first->first)];
  }
  std::vector<int> order(keys.size());
  for (std::size_t c = 0; c < order.size(); ++c) order[c] = static_cast<int>(c);
  std::sort(order.begin(), order.end(), [&keys](int a, int b) { return keys[a] < keys[b]; });
  std::vector<int> begin(keys.size());
  int total = 0;
  for (int c : order) {
    begin[static_cast<std::size_t>(c)] = total;
    total += counts[static_cast<std::size_t>(c)];
  }
  sorted_.resize(static_cast<std::size_t>(total));
  index_.resize(static_cast<std::size_t>(total));
  std::vector<int> next = begin;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (cell_of[i] < 0) continue;
    const int k = next[static_cast<std::size_t>(cell_of[i])]++;
    index_[static_cast<std::size_t>(k)] = static_cast<int>(i);
    sorted_[static_cast<std::size_t>(k)] = points[i];
  }
  cell_list_.reserve(keys.size());
  for (int c : order) {
    const int b = begin[static_cast<std::size_t>(c)], e = b + counts[static_cast<std::size_t>(c)];
    *cells_.find(keys[static_cast<std::size_t>(c)]) = std::make_pair(b, e);
    const Point& p = sorted_[static_cast<std::size_t>(b)];
    cell_list_.push_back({cellOf(p.x()), cellOf(p.y()), cellOf(p.z()), b, e});
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
