#include <fruit_shape_completion/neighbourhood_statistics.h>
#include <fruit_shape_completion/parallel_parts.h>
#include <fruit_shape_completion/spatial_hash_grid.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#if defined(__SSE__)
#include <xmmintrin.h>
#endif

namespace fruit_shape_completion {

namespace {

// Four floats in one SSE register (GCC/Clang vector extension; SSE2 is in x86-64's baseline,
// and other targets get the same arithmetic lane by lane). The per-point sums below are
// reductions, which the compiler may not vectorise itself without -ffast-math.
typedef float Float4 __attribute__((vector_size(16)));
typedef std::int32_t Int4 __attribute__((vector_size(16)));

inline Float4 load4(const float* p) {
  Float4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store4(float* p, Float4 v) { std::memcpy(p, &v, sizeof v); }
inline Float4 splat(float v) { return Float4{v, v, v, v}; }
inline Float4 keepWhere(Float4 v, Int4 mask) { return reinterpret_cast<Float4>(reinterpret_cast<Int4>(v) & mask); }
inline Float4 sqrt4(Float4 v) {
#if defined(__SSE__)
  return reinterpret_cast<Float4>(_mm_sqrt_ps(reinterpret_cast<__m128>(v)));
#else
  return Float4{std::sqrt(v[0]), std::sqrt(v[1]), std::sqrt(v[2]), std::sqrt(v[3])};
#endif
}
inline double laneSum(Float4 v) {
  return static_cast<double>(v[0]) + static_cast<double>(v[1]) + static_cast<double>(v[2]) + static_cast<double>(v[3]);
}

// Sums over the neighbours of a place, coordinates taken relative to that place.
struct Moments {
  double n, sx, sy, sz, xx, xy, xz, yy, yz, zz;
  Eigen::Matrix3d covariance() const {
    const Eigen::Vector3d s(sx, sy, sz);
    Eigen::Matrix3d c;
    c << xx, xy, xz, xy, yy, yz, xz, yz, zz;
    return c - s * s.transpose() / n;
  }
};

// The candidates of one grid cell (the points of it and its 26 neighbours) as floats relative
// to the cell's first point, padded to a multiple of 4 with points far outside any radius.
struct Candidates {
  std::vector<float> x, y, z, dist, near;
  std::size_t count = 0, padded = 0;

  void gather(const SpatialHashGrid& grid, const Point& ref, const std::pair<int, int>* ranges, int nr) {
    count = 0;
    for (int r = 0; r < nr; ++r) count += static_cast<std::size_t>(ranges[r].second - ranges[r].first);
    padded = (count + 3) / 4 * 4;
    if (x.size() < padded) {
      x.resize(padded);
      y.resize(padded);
      z.resize(padded);
      dist.resize(padded);
      near.resize(padded);
    }
    std::size_t m = 0;
    for (int r = 0; r < nr; ++r)
      for (int j = ranges[r].first; j < ranges[r].second; ++j, ++m) {
        const Point q = grid.storedPoint(j) - ref;
        x[m] = static_cast<float>(q.x());
        y[m] = static_cast<float>(q.y());
        z[m] = static_cast<float>(q.z());
      }
    constexpr float kFar = 1e6f;  // squared distance ~1e12: outside every radius, still finite
    for (; m < padded; ++m) x[m] = y[m] = z[m] = kFar;
  }

  // Squared distances from (px, py, pz) to all candidates (into dist) and the moments about it
  // of those within the radius, chosen by mask (no branch per candidate: most fail, and a
  // branch would mispredict often).
  Moments momentsAbout(float px, float py, float pz, float r2) {
    const Float4 vx = splat(px), vy = splat(py), vz = splat(pz), vr2 = splat(r2), one = splat(1.0f);
    Float4 n{}, sx{}, sy{}, sz{}, xx{}, xy{}, xz{}, yy{}, yz{}, zz{};
    for (std::size_t j = 0; j < padded; j += 4) {
      const Float4 dx = load4(&x[j]) - vx, dy = load4(&y[j]) - vy, dz = load4(&z[j]) - vz;
      const Float4 d = dx * dx + dy * dy + dz * dz;
      store4(&dist[j], d);
      const Int4 inside = d <= vr2;
      const Float4 mx = keepWhere(dx, inside), my = keepWhere(dy, inside), mz = keepWhere(dz, inside);
      n += keepWhere(one, inside);
      sx += mx;
      sy += my;
      sz += mz;
      xx += mx * dx;
      xy += mx * dy;
      xz += mx * dz;
      yy += my * dy;
      yz += my * dz;
      zz += mz * dz;
    }
    return {laneSum(n), laneSum(sx), laneSum(sy), laneSum(sz), laneSum(xx),
            laneSum(xy), laneSum(xz), laneSum(yy), laneSum(yz), laneSum(zz)};
  }

  // After momentsAbout() at a point of the cloud: the mean distance to its k nearest others
  // within the radius, or `fallback` if there are fewer. Its own distance 0 is among them, so
  // the k + 1 smallest are wanted.
  double meanNearest(int k, float r2, double fallback) {
    float* d = near.data();
    std::size_t n = 0;
    for (std::size_t j = 0; j < count; ++j) {
      d[n] = dist[j];
      n += dist[j] <= r2 ? 1 : 0;
    }
    const std::size_t want = static_cast<std::size_t>(k) + 1;
    if (n < want) return fallback;
    return (n <= kRankLimit ? sumOfSmallestByRank(d, n, want) : sumOfSmallestByExtraction(d, n, want)) / k;
  }

  // Up to this many in-radius distances (~15-40 on a voxel-merged surface at the defaults) the
  // rank count below wins; beyond it its n^2 compares would not.
  static constexpr std::size_t kRankLimit = 96;

  // Sum of the square roots of the `want` smallest of d[0, n) (d has room up to n rounded up to
  // 4). Each value's rank (how many are smaller) is counted 4 values at a time, compares and
  // adds without branches or a dependency chain; the values ranked below `want` are summed.
  // Equal values share a rank, so a tie at the boundary may take in more than `want`: all the
  // extra ones equal the largest taken, subtracted again.
  static double sumOfSmallestByRank(float* d, std::size_t n, std::size_t want) {
    const std::size_t padded = (n + 3) / 4 * 4;
    for (std::size_t m = n; m < padded; ++m) d[m] = std::numeric_limits<float>::infinity();  // rank n
    const std::int32_t w = static_cast<std::int32_t>(want);
    const Int4 limit{-w, -w, -w, -w};
    Float4 sum{}, largest{};
    Int4 taken{};
    for (std::size_t i = 0; i < padded; i += 4) {
      const Float4 di = load4(d + i);
      Int4 below{};  // minus the count of smaller values, per lane (a true compare is -1)
      for (std::size_t j = 0; j < n; ++j) below += splat(d[j]) < di;
      const Int4 in = below > limit;
      const Float4 v = keepWhere(di, in);
      sum += sqrt4(v);
      taken += in;
      largest = keepWhere(v, v > largest) + keepWhere(largest, v <= largest);
    }
    const std::size_t count = static_cast<std::size_t>(-(taken[0] + taken[1] + taken[2] + taken[3]));
    double total = laneSum(sum);
    if (count > want) {
      const float top = std::max(std::max(largest[0], largest[1]), std::max(largest[2], largest[3]));
      total -= static_cast<double>(count - want) * std::sqrt(static_cast<double>(top));
    }
    return total;
  }

  // The same by repeated extraction from whichever end is shorter, for large neighbourhoods.
  static double sumOfSmallestByExtraction(float* d, std::size_t n, std::size_t want) {
    if (n - want < want) {
      for (; n > want; --n) {  // drop the largest
        std::size_t arg = 0;
        float best = d[0];
        for (std::size_t j = 1; j < n; ++j) {
          const bool larger = d[j] > best;
          best = larger ? d[j] : best;
          arg = larger ? j : arg;
        }
        d[arg] = d[n - 1];
      }
    } else {
      for (std::size_t s = 0; s < want; ++s) {  // move the smallest to the front
        std::size_t arg = s;
        float best = d[s];
        for (std::size_t j = s + 1; j < n; ++j) {
          const bool smaller = d[j] < best;
          best = smaller ? d[j] : best;
          arg = smaller ? j : arg;
        }
        d[arg] = d[s];
        d[s] = best;
      }
    }
    double sum = 0.0;
    for (std::size_t j = 0; j < want; ++j) sum += std::sqrt(static_cast<double>(d[j]));
    return sum;
  }
};

// The surface normal of a neighbourhood with covariance c: the eigenvector of its smallest
// eigenvalue, found by power iteration on the adjugate (whose eigenvalues are the products of
// the other two: on a surface the normal's is far the largest), started from the adjugate's
// largest column, already close to it. NaN unless the neighbourhood spans a surface: a line's
// (second eigenvalue under 5 % of the largest) has no normal.
Eigen::Vector3d surfaceNormal(const Eigen::Matrix3d& c) {
  const Eigen::Vector3d none = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Matrix3d adj;  // adjugate of the symmetric c
  adj(0, 0) = c(1, 1) * c(2, 2) - c(1, 2) * c(1, 2);
  adj(1, 1) = c(0, 0) * c(2, 2) - c(0, 2) * c(0, 2);
  adj(2, 2) = c(0, 0) * c(1, 1) - c(0, 1) * c(0, 1);
  adj(0, 1) = adj(1, 0) = c(0, 2) * c(1, 2) - c(0, 1) * c(2, 2);
  adj(0, 2) = adj(2, 0) = c(0, 1) * c(1, 2) - c(0, 2) * c(1, 1);
  adj(1, 2) = adj(2, 1) = c(0, 1) * c(0, 2) - c(0, 0) * c(1, 2);
  int col = 0;
  if (adj(1, 1) > adj(col, col)) col = 1;
  if (adj(2, 2) > adj(col, col)) col = 2;
  // Two steps, normalised once at the end: the entries (products of two variances, ~1e-9 m^4
  // at a 1 cm radius) shrink with each step but stay far above double's range.
  Eigen::Vector3d n = adj * (adj * adj.col(col));
  const double len = n.norm();
  if (!(len > 0.0) || !std::isfinite(len)) return none;
  n /= len;
  // The other two eigenvalues, from the covariance within the tangent plane: its trace and its
  // determinant (n' adj n = their product).
  const double t = c.trace() - n.dot(c * n), d = n.dot(adj * n);
  const double half_gap = std::sqrt(std::max(0.0, 0.25 * t * t - d));
  const double second = 0.5 * t - half_gap, largest = 0.5 * t + half_gap;
  return second > 0.05 * largest ? n : none;
}

// Cells [first, last) of the grid: the candidates of a cell (the points of it and its
// neighbours) are gathered once for all its points. Read-only over the grid, one output slot
// per point: thread-safe for disjoint cell ranges.
void analyseCells(const SpatialHashGrid& grid, std::size_t first, std::size_t last, const NeighbourhoodQuery& q,
                  double* knn, Eigen::Vector3d* normals) {
  Candidates cand;
  const float r2 = static_cast<float>(q.radius * q.radius);
  grid.forEachCell(first, last, [&](const SpatialHashGrid::Cell& cell, const std::pair<int, int>* ranges, int nr) {
    const Point ref = grid.storedPoint(cell.begin);
    cand.gather(grid, ref, ranges, nr);
    for (int j = cell.begin; j < cell.end; ++j) {
      const Point p = grid.storedPoint(j) - ref;
      const std::size_t i = static_cast<std::size_t>(grid.originalIndex(j));
      // m.n counts the point itself (distance 0, nothing added to the sums).
      const Moments m = cand.momentsAbout(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                          static_cast<float>(p.z()), r2);
      if (normals != nullptr && m.n >= 5) normals[i] = surfaceNormal(m.covariance());
      if (knn != nullptr) knn[i] = cand.meanNearest(q.k, r2, q.radius);
    }
  });
}

}  // namespace

void analyseNeighbourhoods(const PointList& points, const NeighbourhoodQuery& query, std::vector<double>* knn,
                           std::vector<Eigen::Vector3d>* normals, SpatialHashGrid* grid_scratch) {
  const bool want_knn = knn != nullptr && query.k > 0;
  const bool want_normals = normals != nullptr && query.normals;
  if (want_knn) {
    knn->assign(points.size(), query.radius);
    for (std::size_t i = 0; i < points.size(); ++i)
      if (!points[i].allFinite()) (*knn)[i] = std::numeric_limits<double>::quiet_NaN();
  }
  if (want_normals)
    normals->assign(points.size(), Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  if (!(want_knn || want_normals) || points.empty() || !(query.radius > 0.0) || !std::isfinite(query.radius))
    return;
  SpatialHashGrid own_grid;
  SpatialHashGrid& grid = grid_scratch != nullptr ? *grid_scratch : own_grid;
  grid.build(points, query.radius);
  const std::size_t cells = grid.cells().size();
  const std::size_t parts = static_cast<std::size_t>(std::max(1, query.threads));
  runParts(parts, [&](std::size_t t) {
    analyseCells(grid, cells * t / parts, cells * (t + 1) / parts, query, want_knn ? knn->data() : nullptr,
                 want_normals ? normals->data() : nullptr);
  });
}

}  // namespace fruit_shape_completion
