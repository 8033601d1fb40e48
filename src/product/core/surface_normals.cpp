#include <fruit_shape_completion/neighbour_grid.h>
#include <fruit_shape_completion/surface_normals.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace fruit_shape_completion {

Eigen::Vector3d NeighbourMoments::normal(const NormalParams& params) const {
  const Eigen::Vector3d none = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  if (count < params.min_neighbours) return none;
  const Eigen::Vector3d mean = sum / count;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  Eigen::Matrix3d second;
  second << outer[0], outer[1], outer[2], outer[1], outer[3], outer[4], outer[2], outer[4], outer[5];
  es.computeDirect(second - count * mean * mean.transpose());
  const Eigen::Vector3d ev = es.eigenvalues();  // ascending
  if (!(ev(2) > 0.0) || ev(1) < params.min_planarity * ev(2)) return none;
  const Eigen::Vector3d normal = es.eigenvectors().col(0);
  if (!normal.allFinite() || normal.norm() < 0.5) return none;
  return normal.normalized();
}

// The PCA normal of pcl::NormalEstimation, over a NeighbourGrid (docs/benchmarks.md). That class
// is not used as it is: it gives a normal to any neighbourhood of 3 points, a line included, and
// the centre prior must not take the arbitrary normal of a line.
SurfaceNormals estimateNormals(const PointList& points, const NormalParams& params, const Eigen::Vector3d& inside) {
  SurfaceNormals out;
  out.normals.assign(points.size(), Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  if (points.empty() || !(params.radius > 0.0)) return out;
  const NeighbourGrid grid(points, params.radius);
  const std::size_t n = points.size();
  const std::size_t step =
      params.max_points > 0 ? std::max<std::size_t>(1, (n + params.max_points - 1) / params.max_points) : 1;
  grid.forEachPoint(params.radius, [&](int index, auto&& within) {
    const std::size_t i = static_cast<std::size_t>(index);
    if (i % step != 0) return;
    NeighbourMoments m;  // relative to the point: numerically safe
    within([&](int, double, const Point& q) { m.add(q - points[i]); });
    Eigen::Vector3d normal = m.normal(params);
    if (!normal.allFinite()) return;
    if (params.max_edge_offset > 0.0) {
      const Eigen::Vector3d mean = m.sum / m.count;
      if ((mean - mean.dot(normal) * normal).norm() > params.max_edge_offset * params.radius) return;
    }
    if (normal.dot(inside - points[i]) < 0.0) normal = -normal;
    out.normals[i] = normal;
    ++out.valid;
  });
  return out;
}

}  // namespace fruit_shape_completion
