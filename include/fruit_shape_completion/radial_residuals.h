#pragma once
// The fit's data term: the radial distance of each point from a posed superellipsoid, d_i =
// |r0| |1 - F^(-e1/2)|, with its analytic Jacobian over the 11 parameters.
#include <fruit_shape_completion/superellipsoid.h>

#include <Eigen/Dense>

#include <cstddef>
#include <vector>

namespace ceres {
class CostFunction;
}

namespace fruit_shape_completion {

// One Ceres cost over all the points (the rotation and its derivatives computed once per
// evaluation); parameter blocks shape (a, b, c, e1, e2), translation (3), rpy (3). The caller
// (a ceres::Problem) owns it.
ceres::CostFunction* newRadialResiduals(const std::vector<Point>& points);

// The fit's data term for inspection and tests: the signed radial residuals of the points and
// (if J is given) their N x 11 Jacobian, columns a, b, c, e1, e2, tx, ty, tz, roll, pitch, yaw.
void evaluateRadialResiduals(const PointList& points, const Superellipsoid& shape,
                             Eigen::VectorXd* residuals, Eigen::MatrixXd* J);

// The radial distances of many points at once (vectorised; Superellipsoid::radialDistance is the
// one-point form), and their RMS (0 for no points).
Eigen::VectorXd radialDistances(const PointList& points, const Superellipsoid& shape);
double rmsRadialDistance(const PointList& points, const Superellipsoid& shape);

// At most `at_most` of the points, evenly strided (point floor(i n / at_most) for i < at_most):
// what the fit's final solve and the volume spread evaluate the data term on. All of them when
// there are no more.
PointList evenlyStrided(const PointList& points, std::size_t at_most);

}  // namespace fruit_shape_completion
