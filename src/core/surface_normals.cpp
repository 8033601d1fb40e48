#include <fruit_shape_completion/spatial_hash_grid.h>
#include <fruit_shape_completion/surface_normals.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace fruit_shape_completion {

SurfaceNormals estimateNormals(const PointList& points, const NormalParams& params,
                               const Eigen::Vector3d& inside) {
  SurfaceNormals out;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  out.normals.assign(points.size(), Eigen::Vector3d::Constant(nan));
  if (points.empty() || !(params.radius > 0.0)) return out;
  const SpatialHashGrid grid(points, params.radius);
  const size_t step =
      params.max_points > 0 ? std::max<size_t>(1, (points.size() + params.max_points - 1) / params.max_points) : 1;
  for (size_t i = 0; i < points.size(); i += step) {
    if (!points[i].allFinite()) continue;
    // Moments relative to the query point (numerically safe), accumulated during the search.
    int count = 0;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
    grid.visitWithin(points[i], params.radius, [&](const Point& q, int) {
      const Eigen::Vector3d d = q - points[i];
      ++count;
      sum += d;
      outer.noalias() += d * d.transpose();
      return true;
    });
    if (count < params.min_neighbours) continue;
    const Eigen::Vector3d mean = sum / count;
    const Eigen::Matrix3d cov = outer - count * mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(cov);
    const Eigen::Vector3d ev = es.eigenvalues();  // ascending
    if (!(ev(2) > 0.0) || ev(1) < params.min_planarity * ev(2)) continue;
    Eigen::Vector3d n = es.eigenvectors().col(0);
    if (!n.allFinite() || n.norm() < 0.5) continue;
    n.normalize();
    if (n.dot(inside - points[i]) < 0.0) n = -n;
    out.normals[i] = n;
    ++out.valid;
  }
  return out;
}

}  // namespace fruit_shape_completion
