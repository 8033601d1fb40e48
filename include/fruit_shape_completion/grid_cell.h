#pragma once
// Integer cells of a regular grid: the one place points are floored to cells and cells packed
// into hash keys (TSDF voxels and blocks, the per-view merge, fruit tracking).
#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace fruit_shape_completion {

using GridCell = Eigen::Matrix<std::int64_t, 3, 1>;

// The cell holding p; coordinates are clamped far beyond any key's range so no conversion
// overflows (a NaN lands on a bound: callers skip non-finite points first).
inline GridCell cellOf(const Eigen::Vector3d& p, double inv_cell_size) {
  GridCell c;
  for (int k = 0; k < 3; ++k) {
    const double v = std::floor(p[k] * inv_cell_size);
    c[k] = static_cast<std::int64_t>(std::min(4.0e15, std::max(-4.0e15, std::isnan(v) ? 0.0 : v)));
  }
  return c;
}

// 21 bits per axis: unique for cells within +-2^20 of the origin (+-10 km at 1 cm).
inline std::uint64_t packCellKey(const GridCell& c) {
  const std::uint64_t mask = (std::uint64_t(1) << 21) - 1;
  return ((static_cast<std::uint64_t>(c.x()) & mask) << 42) | ((static_cast<std::uint64_t>(c.y()) & mask) << 21) |
         (static_cast<std::uint64_t>(c.z()) & mask);
}

}  // namespace fruit_shape_completion
