#pragma once
// The fruit centre prior w: the least-squares intersection of the normal lines, pulled toward
// the cluster mean by an L2 term, and a check that a cluster has a shape worth fitting.
#include <fruit_shape_completion/types.h>

#include <string>
#include <vector>

namespace fruit_shape_completion {

// Minimises sum_i |(I - n_i n_i^T)(w - p_i)|^2 + lambda |w - mean|^2 over the points with a
// finite normal. The pull only matters where the normals do not pin the centre down (nearly
// parallel normals of a flat patch), and keeps w finite there. Returns the mean if no point has
// a normal.
Eigen::Vector3d estimateFruitCenter(const PointList& points,
                                    const std::vector<Eigen::Vector3d>& normals, double lambda);

struct ClusterShapeCheck {
  bool ok = true;
  std::string reason;  // empty when ok
};

// Rejects clusters no superellipsoid can be fitted to meaningfully: collinear points, or a
// flat patch whose normals are all (nearly) parallel.
ClusterShapeCheck checkClusterShape(const PointList& points,
                                    const std::vector<Eigen::Vector3d>& normals);

}  // namespace fruit_shape_completion
