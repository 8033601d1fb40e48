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

// The centre of the sphere through the points (linear least squares on |p - c|^2 = r^2), or NaN
// if the points do not pin one down (fewer than 4, all in a plane or on a line, or a centre over
// 8 cm from their mean).
Eigen::Vector3d sphereCenter(const PointList& points);

// How firmly the normal lines hold the centre along their weakest direction: the smallest
// eigenvalue of the mean of (I - n n^T) over the finite normals, the mean squared sine of the
// normals' angle to that direction. For a sphere: 2/3 seen over a hemisphere or more, 1/2 over
// 32 % of it, 5/12 over a quarter. 0 without normals.
double normalLineHold(const std::vector<Eigen::Vector3d>& normals);

// The prior the pipeline fits from: estimateFruitCenter where the normals hold the centre, the
// sphere centre where they hold it little (a cap of about a quarter or less), and a blend
// between. Over a small cap the normal lines meet at a depth each tilt of the one-sided rim
// normals moves, and the fit's centre (hence its volume) follows the prior; the sphere through
// the points is held by their curvature instead.
struct CenterPriorBlend {
  double sphere_below = 0.4;   // normalLineHold at or below this: the sphere centre alone
  double normals_above = 0.5;  // at or above this: the normal lines alone
};
Eigen::Vector3d blendedFruitCenter(const PointList& points, const std::vector<Eigen::Vector3d>& normals,
                                   double lambda, const CenterPriorBlend& blend = CenterPriorBlend());

struct ClusterShapeCheck {
  bool ok = true;
  std::string reason;  // empty when ok
};

// Rejects clusters no superellipsoid can be fitted to meaningfully: collinear points, or a
// flat patch whose normals are all (nearly) parallel.
ClusterShapeCheck checkClusterShape(const PointList& points,
                                    const std::vector<Eigen::Vector3d>& normals);

}  // namespace fruit_shape_completion
