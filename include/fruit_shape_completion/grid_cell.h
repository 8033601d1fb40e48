#pragma once
// Integer cells of a regular grid: the one place points are floored to cells and cells packed
// into hash keys (TSDF voxels and blocks, the per-view merge, fruit tracking).
#include <Eigen/Core>

#include <algorithm>
#include <cstdint>

namespace fruit_shape_completion {

using GridCell = Eigen::Matrix<std::int64_t, 3, 1>;

// floor(v) as an integer, clamped far beyond any key's range so no conversion overflows (a NaN
// lands on a bound: callers skip non-finite points first). Without a libm call: baseline x86-64
// has no rounding instruction, and this runs for every point of every view.
inline std::int64_t floorToCell(double v) {
  v = std::min(4.0e15, std::max(-4.0e15, v));
  const auto c = static_cast<std::int64_t>(v);
  return c - (static_cast<double>(c) > v ? 1 : 0);
}

// The cell holding p.
inline GridCell cellOf(const Eigen::Vector3d& p, double inv_cell_size) {
  return GridCell(floorToCell(p.x() * inv_cell_size), floorToCell(p.y() * inv_cell_size),
                  floorToCell(p.z() * inv_cell_size));
}

// 21 bits per axis: unique for cells within +-2^20 of the origin (+-10 km at 1 cm).
inline std::uint64_t packCellKey(const GridCell& c) {
  const std::uint64_t mask = (std::uint64_t(1) << 21) - 1;
  return ((static_cast<std::uint64_t>(c.x()) & mask) << 42) | ((static_cast<std::uint64_t>(c.y()) & mask) << 21) |
         (static_cast<std::uint64_t>(c.z()) & mask);
}

}  // namespace fruit_shape_completion
