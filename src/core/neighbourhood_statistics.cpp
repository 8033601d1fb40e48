#include <fruit_shape_completion/neighbourhood_statistics.h>
#include <fruit_shape_completion/parallel_parts.h>
#include <fruit_shape_completion/spatial_hash_grid.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

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
  // the k + 1 smallest are wanted; found by repeated extraction from whichever end is shorter
  // (typically ~15 neighbours for k = 10: four maxima out), without a sort's mispredictions.
  double meanNearest(int k, float r2, double fallback) {
    float* d = near.data();
    std::size_t n = 0;
    for (std::size_t j = 0; j < count; ++j) {
      d[n] = dist[j];
      n += dist[j] <= r2 ? 1 : 0;
    }
    const std::size_t want = static_cast<std::size_t>(k) + 1;
    if (n < want) return fallback;
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
    return sum / k;
  }
};

// Cells [first, last) of the grid. One eigen-decomposition per cell gives the cell's normal;
// each point refines it by two steps of inverse iteration on its own neighbourhood's covariance
// (the adjugate stands in for the inverse: the scale does not matter), which converges fast on
// a surface, whose smallest eigenvalue is far below the others, and costs a fraction of a
// solver call. Read-only over the grid, one output slot per point: thread-safe for disjoint
// cell ranges.
void analyseCells(const SpatialHashGrid& grid, std::size_t first, std::size_t last, const NeighbourhoodQuery& q,
                  double* knn, Eigen::Vector3d* normals) {
  Candidates cand;
  const float r2 = static_cast<float>(q.radius * q.radius);
  grid.forEachCell(first, last, [&](const SpatialHashGrid::Cell& cell, const std::pair<int, int>* ranges, int nr) {
    const Point ref = grid.storedPoint(cell.begin);
    cand.gather(grid, ref, ranges, nr);

    Eigen::Vector3d cell_normal = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    if (normals != nullptr) {  // from the neighbourhood of the centroid of the cell's points
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (int j = cell.begin; j < cell.end; ++j) c += grid.storedPoint(j) - ref;
      c /= cell.end - cell.begin;
      const Moments m = cand.momentsAbout(static_cast<float>(c.x()), static_cast<float>(c.y()),
                                          static_cast<float>(c.z()), r2);
      if (m.n >= 5) {
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
        es.computeDirect(m.covariance());
        if (es.eigenvalues()(1) > 0.05 * es.eigenvalues()(2)) cell_normal = es.eigenvectors().col(0);
      }
    }

    for (int j = cell.begin; j < cell.end; ++j) {
      const Point p = grid.storedPoint(j) - ref;
      const std::size_t i = static_cast<std::size_t>(grid.originalIndex(j));
      // m.n counts the point itself (distance 0, nothing added to the sums).
      const Moments m = cand.momentsAbout(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                          static_cast<float>(p.z()), r2);
      if (normals != nullptr && m.n >= 5 && cell_normal.allFinite()) {
        const Eigen::Matrix3d c = m.covariance();
        Eigen::Matrix3d adj;  // adjugate of the symmetric c
        adj(0, 0) = c(1, 1) * c(2, 2) - c(1, 2) * c(1, 2);
        adj(1, 1) = c(0, 0) * c(2, 2) - c(0, 2) * c(0, 2);
        adj(2, 2) = c(0, 0) * c(1, 1) - c(0, 1) * c(0, 1);
        adj(0, 1) = adj(1, 0) = c(0, 2) * c(1, 2) - c(0, 1) * c(2, 2);
        adj(0, 2) = adj(2, 0) = c(0, 1) * c(1, 2) - c(0, 2) * c(1, 1);
        adj(1, 2) = adj(2, 1) = c(0, 1) * c(0, 2) - c(0, 0) * c(1, 2);
        Eigen::Vector3d n = cell_normal;
        for (int step = 0; step < 2; ++step) {
          const Eigen::Vector3d next = adj * n;
          const double len = next.norm();
          if (!(len > 0.0) || !std::isfinite(len)) break;  // degenerate: keep what we have
          n = next / len;
        }
        normals[i] = n;
      }
      if (knn != nullptr) knn[i] = cand.meanNearest(q.k, r2, q.radius);
    }
  });
}

}  // namespace

void analyseNeighbourhoods(const PointList& points, const NeighbourhoodQuery& query, std::vector<double>* knn,
                           std::vector<Eigen::Vector3d>* normals) {
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
  const SpatialHashGrid grid(points, query.radius);
  const std::size_t cells = grid.cells().size();
  const std::size_t parts = static_cast<std::size_t>(std::max(1, query.threads));
  runParts(parts, [&](std::size_t t) {
    analyseCells(grid, cells * t / parts, cells * (t + 1) / parts, query, want_knn ? knn->data() : nullptr,
                 want_normals ? normals->data() : nullptr);
  });
}

}  // namespace fruit_shape_completion
