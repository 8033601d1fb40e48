#include <fruit_shape_completion/spatial_hash_grid.h>

#include <algorithm>
#include <climits>

namespace fruit_shape_completion {

namespace {

// Cell coordinate of v / cell, wrapped into 21 bits (packKey keeps 21 bits per axis, so cells
// 2^21 apart share a key either way). No std::floor call, and no undefined conversion for
// values beyond the int64 range or NaN (a zero coordinate times an infinite inverse cell size).
inline std::int32_t wrappedCell(double scaled) {
  constexpr double kClamp = 4.0e15;  // far beyond 2^21 cells, well inside int64
  scaled = std::min(kClamp, std::max(-kClamp, scaled));  // NaN -> -kClamp
  std::int64_t c = static_cast<std::int64_t>(scaled);
  c -= static_cast<double>(c) > scaled ? 1 : 0;
  constexpr std::int64_t kHalf = std::int64_t(1) << 20;
  return static_cast<std::int32_t>(((c + kHalf) & ((kHalf << 1) - 1)) - kHalf);
}

int bitsFor(std::uint32_t v) {
  int b = 0;
  while (b < 32 && (v >> b) != 0) ++b;
  return b;
}

}  // namespace

SpatialHashGrid::SpatialHashGrid(const PointList& points, double cell_size) { build(points, cell_size); }

void SpatialHashGrid::build(const PointList& points, double cell_size) {
  cell_ = cell_size;
  inv_cell_ = 1.0 / cell_size;
  sorted_.clear();
  index_.clear();
  cell_list_.clear();
  // Radix sort: each finite point gets its cell's (x, y, z) packed densely over the cloud's
  // bounding box, so that the keys compare as the cells' (x, y, z) order (forEachCell relies
  // on it); a stable LSD radix sort of (key, index) then leaves every cell's points together in
  // index order, in a few linear passes and without a hash lookup per point.
  const std::size_t n = points.size();
  std::int32_t lo[3] = {INT32_MAX, INT32_MAX, INT32_MAX}, hi[3] = {INT32_MIN, INT32_MIN, INT32_MIN};
  std::size_t finite = 0;
  for (const Point& p : points) {
    if (!p.allFinite()) continue;
    ++finite;
    for (int a = 0; a < 3; ++a) {
      const std::int32_t c = wrappedCell(p[a] * inv_cell_);
      lo[a] = c < lo[a] ? c : lo[a];
      hi[a] = c > hi[a] ? c : hi[a];
    }
  }
  if (finite == 0) {
    cells_.reset(0);
    return;
  }
  int bits[3];
  for (int a = 0; a < 3; ++a) bits[a] = bitsFor(static_cast<std::uint32_t>(hi[a] - lo[a]));  // <= 21 each
  const int shift_x = bits[1] + bits[2], shift_y = bits[2];
  std::vector<std::uint64_t>& key = key_;
  std::vector<std::uint64_t>& key_tmp = key_tmp_;
  std::vector<int>& order = index_;
  std::vector<int>& order_tmp = order_tmp_;
  key.resize(finite);
  key_tmp.resize(finite);
  order.resize(finite);
  order_tmp.resize(finite);
  std::size_t m = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Point& p = points[i];
    if (!p.allFinite()) continue;
    key[m] = (static_cast<std::uint64_t>(wrappedCell(p.x() * inv_cell_) - lo[0]) << shift_x) |
             (static_cast<std::uint64_t>(wrappedCell(p.y() * inv_cell_) - lo[1]) << shift_y) |
             static_cast<std::uint64_t>(wrappedCell(p.z() * inv_cell_) - lo[2]);
    order[m++] = static_cast<int>(i);
  }
  constexpr int kDigitBits = 11;
  constexpr std::size_t kBuckets = std::size_t(1) << kDigitBits;
  std::vector<std::size_t> offset(kBuckets);
  for (int low = 0; low < bits[0] + bits[1] + bits[2]; low += kDigitBits) {
    std::fill(offset.begin(), offset.end(), 0);
    for (std::size_t k = 0; k < finite; ++k) ++offset[(key[k] >> low) & (kBuckets - 1)];
    if (*std::max_element(offset.begin(), offset.end()) == finite) continue;  // one digit: in order
    std::size_t total = 0;
    for (std::size_t& o : offset) {
      const std::size_t c = o;
      o = total;
      total += c;
    }
    for (std::size_t k = 0; k < finite; ++k) {
      const std::size_t dst = offset[(key[k] >> low) & (kBuckets - 1)]++;
      key_tmp[dst] = key[k];
      order_tmp[dst] = order[k];
    }
    key.swap(key_tmp);
    order.swap(order_tmp);
  }

  sorted_.resize(finite);
  for (std::size_t k = 0; k < finite; ++k) sorted_[k] = points[static_cast<std::size_t>(index_[k])];
  const std::uint64_t mask_y = (std::uint64_t(1) << bits[1]) - 1, mask_z = (std::uint64_t(1) << bits[2]) - 1;
  for (std::size_t k = 0; k < finite;) {
    std::size_t e = k + 1;
    while (e < finite && key[e] == key[k]) ++e;
    cell_list_.push_back({lo[0] + static_cast<std::int64_t>(key[k] >> shift_x),
                          lo[1] + static_cast<std::int64_t>((key[k] >> shift_y) & mask_y),
                          lo[2] + static_cast<std::int64_t>(key[k] & mask_z), static_cast<int>(k),
                          static_cast<int>(e)});
    k = e;
  }
  cells_.reset(cell_list_.size());
  for (const Cell& c : cell_list_) *cells_.insert(packKey(c.x, c.y, c.z)).first = std::make_pair(c.begin, c.end);
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
