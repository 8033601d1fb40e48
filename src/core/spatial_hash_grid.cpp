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
  std::uint64_t last_key = FlatHashMap<std::pair<int, int>>::kEmpty;
  int last_cell = -1;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Point& p = points[i];
    if (!p.allFinite()) continue;
    const std::uint64_t key = packKey(cellOf(p.x()), cellOf(p.y()), cellOf(p.z()));
    if (key != last_key) {  // neighbouring points (scan order) often share a cell
      const auto ins = cells_.insert(key);
      if (ins.second) {
        ins.first->first = static_cast<int>(keys.size());
        keys.push_back(key);
        counts.push_back(0);
      }
      last_key = key;
      last_cell = ins.first->first;
    }
    cell_of[i] = last_cell;
    ++counts[static_cast<std::size_t>(last_cell)];
  }
  // In (x, y, z) order, negative coordinates first (forEachCell relies on it): flipping the top
  // bit of each 21-bit field makes the packed keys compare as the signed coordinates do.
  constexpr std::uint64_t kSignBits = (1ull << 62) | (1ull << 41) | (1ull << 20);
  std::vector<std::pair<std::uint64_t, int>> order(keys.size());
  for (std::size_t c = 0; c < order.size(); ++c) order[c] = {keys[c] ^ kSignBits, static_cast<int>(c)};
  std::sort(order.begin(), order.end());
  std::vector<int> begin(keys.size());
  int total = 0;
  for (const auto& o : order) {
    begin[static_cast<std::size_t>(o.second)] = total;
    total += counts[static_cast<std::size_t>(o.second)];
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
  for (const auto& o : order) {
    const std::size_t c = static_cast<std::size_t>(o.second);
    const int b = begin[c], e = b + counts[c];
    *cells_.find(keys[c]) = std::make_pair(b, e);
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
