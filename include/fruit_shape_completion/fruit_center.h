#pragma once
// The fruit centre prior w: the least-squares intersection of the normal lines, pulled toward
// the cluster mean by an L2 term, and a check that a cluster has a shape worth fitting.
#include <fruit_shape_completion/types.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace fruit_shape_completion {

// Minimises sum_i |(I - n_i n_i^T)(w - p_i)|^2 + lambda |w - mean|^2 over the points with a
// finite normal. The pull only matters where the normals do not pin the centre down (nearly
// parallel normals of a flat patch), and keeps w finite there. Returns the mean if no point has
// a normal.
Eigen::Vector3d estimateFruitCenter(const PointList& points,
                                    const std::vector<Eigen::Vector3d>& normals, double lambda);

// The sphere through the points (linear least squares on |p - c|^2 = r^2). Not valid (NaN) for
// fewer than 4 finite points, points nearly in a plane or on a line (their thinnest spread under
// 5 % of their widest), or a centre over 8 cm from their mean.
struct SphereFit {
  Eigen::Vector3d center = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double radius = std::numeric_limits<double>::quiet_NaN();
  bool valid() const { return center.allFinite() && std::isfinite(radius); }
};
SphereFit fitSphere(const PointList& points);

// How firmly the normal lines hold the centre along their weakest direction: the smallest
// eigenvalue of the mean of (I - n n^T) over the points with a finite normal (those
// estimateFruitCenter uses), the mean squared sine of the normals' angle to that direction. For
// a sphere seen over a cap: 2/3 at a hemisphere and all round (0.625-2/3 between), 1/2 at 32 %
// seen, 5/12 at a quarter; a flattened or elongated fruit holds less at any share. 0 without
// normals.
double normalLineHold(const PointList& points, const std::vector<Eigen::Vector3d>& normals);

// A fruit seen from one side has its centre behind what was seen, but not behind the deepest
// part of it, the outline where the view grazes the surface: that lies a little in front of a
// convex fruit's centre (R^2 / d for a sphere seen from distance d) or, blurred by the depth
// camera, a few millimetres behind it. Along the direction the normals face on average (into
// the fruit, from the seen side), `center` is moved forward to at most the points' 99th
// percentile depth plus `margin`. Where the normal lines meet far behind the outline (a blocky
// fruit's steep sides seen from one side, whose normals tilt alike) the fit would follow the
// prior into a fruit far too large. Where the fruit was seen all round, its deepest points lie
// on its far side and nothing moves. A negative margin, or fewer than 10 normals, leaves
// `center` as it is.
Eigen::Vector3d limitToSeenDepth(const PointList& points, const std::vector<Eigen::Vector3d>& normals,
                                 const Eigen::Vector3d& center, double margin);

// The prior the pipeline fits from: estimateFruitCenter, moved toward the centre of the sphere
// through the points where the normal lines hold the centre little and the fruit is small. Over
// a small cap of a small fruit the normals' neighbourhood (1.5 cm) spans much of the cap, the
// one-sided rim normals tilt, the lines meet at a depth each tilt moves, and the fit's centre
// (hence its volume) follows the prior; the sphere through the points is held by their
// curvature instead. On a large fruit the normals are sound and the sphere through a small cap
// of a shape that is no sphere misleads, so it is left out there. Without normals: the sphere
// centre if it is valid and small enough, else the points' mean. Then limitToSeenDepth, where
// the normal lines scatter about the point they meet at (RMS distance at least
// rim_min_line_spread: lobes, a blocky fruit's steep sides, noise); lines that meet closely (a
// sphere-like fruit) hold the centre even where the seen part ends in front of it, as where a
// camera lost the grazing rim or leaves leave a gap.
struct CenterPriorBlend {
  double sphere_below = 0.4;   // normalLineHold at or below this: the sphere's full weight
  double normals_above = 0.5;  // at or above this: the normal lines alone
  double sphere_radius_full = 0.035;  // the sphere's radius [m] up to which it keeps its weight
  double sphere_radius_none = 0.045;  // ... and from which it has none
  // limitToSeenDepth's margin [m]; negative: no limit. Off here: the pipeline passes its
  // PipelineParams::center_rim_margin (3 mm by default); a direct caller chooses.
  double rim_margin = -1.0;
  double rim_min_line_spread = 0.003;  // [m] the limit applies from this scatter of the lines on
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
