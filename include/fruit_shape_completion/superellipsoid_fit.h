#pragma once
// Fits a posed superellipsoid (11 parameters) to a fruit's surface points with Ceres
// Levenberg-Marquardt, minimising
//   sum_i d_i^2 + N alpha |t - w|^2 + N gamma ((a-b)^2 + (b-c)^2 + (c-a)^2) + N kappa log(abc)
// d_i the radial distance of point i, w the centre prior, N the number of points, kappa the size
// prior; the result is then shrunk by the outward offset that noise gives such a fit
// (FitParams::noise_bias).
#include <fruit_shape_completion/radial_residuals.h>
#include <fruit_shape_completion/superellipsoid.h>

#include <Eigen/Dense>

#include <string>

namespace fruit_shape_completion {

struct FitParams {
  // Prior weights. The paper uses alpha = gamma = 0.1; on synthetic fruits seen from one side
  // these pull the fit toward the (biased) normal-line centre and toward a sphere, costing
  // several percent of volume accuracy (README, "Fit parameters"), so the defaults are weaker.
  double alpha = 0.01;  // centre prior weight
  double gamma = 0.0;   // axis similarity weight
  double min_axis = 0.02, max_axis = 0.15;  // bounds of a, b, c [m]
  double min_e = 0.3, max_e = 0.9;          // bounds of e1, e2
  double initial_axis = 0.05;
  double initial_e = 0.5;
  int max_iterations = 100;  // per start
  // The final solve runs on at most this many of the points, evenly strided (the residual and
  // the acceptance use all of them): a fruit seen all round gives thousands of surface points
  // that add cost, not information. 0: all points.
  int max_points = 300;
  // Also start with the shape's z axis along world x and y, keep the lowest cost. Guards
  // against the local minima of a single start at rpy = 0.
  bool extra_starts = true;
  // A solve ends when an iteration changes the cost by less than this fraction (Ceres' function
  // tolerance). 1e-4 halves the fit time but measured 1.6 fewer MA50 fruits on scenario 2.
  double function_tolerance = 1e-6;
  // A solve also ends when its last 5 accepted steps together lowered the cost by less than this
  // fraction: on noisy surfaces LM crawls along flat valleys (the exponents trading against the
  // axes) for tens of steps the data cannot tell apart. 0: off.
  double stall_tolerance = 1e-3;
  // A converged fit whose RMS radial residual exceeds this is implausible and rejected.
  double max_rms = 0.006;
  // The fitted shape is shrunk by noise_bias x sigma^2 / R (R the geometric mean semi-axis,
  // sigma the residuals' robust spread, 1.4826 MAD, at most the RMS and 3 mm): a point that
  // noise moves along a curved surface lies farther from the centre than the surface, by
  // sigma^2 / R on a sphere with isotropic noise sigma, so a radial least-squares fit lies
  // outside the surface by about that much (3 sigma^2 / R^2 of the volume). 0: off.
  double noise_bias = 1.0;
  // A pull toward smaller shapes: the cost gains N size_prior log(abc) [m^2 per unit of log
  // volume]. Where the points leave the size free (a fruit seen from one side, whose depth slides
  // along the view axis) it picks the smallest of the shapes that explain them nearly alike: there
  // the least-squares fit of a lobed or noisy half errs large far more often than small, the
  // radial residuals falling slowly as the shape grows deeper. Where the points pin the size down
  // it moves a fit inward by only 1.5 size_prior / R (R the mean semi-axis; 0.1 mm, 1 % of the
  // volume, on a 3 cm fruit). 0: off.
  double size_prior = 2e-6;
  // Throws std::invalid_argument naming the first bad value.
  void validate() const;
};

struct FitResult {
  Superellipsoid shape;
  bool converged = false;  // the solver reached its tolerances within max_iterations
  bool accepted = false;   // converged and plausible; only accepted fits are published
  std::string reason;      // why a fit was rejected; empty when accepted
  int iterations = 0;      // summed over all starts
  double rms = 0.0;        // RMS radial residual over the points [m], of the fit before its noise bias is removed
  double seconds = 0.0;    // wall time of the fit
  double noise_scale = 1.0;  // the factor the axes were shrunk by (FitParams::noise_bias)
};

// `initial`: start from a previous fit (its shape is clamped into the bounds); otherwise the
// paper's start: a = b = c = initial_axis, e1 = e2 = initial_e, t = center_prior, rpy = 0.
FitResult fitSuperellipsoid(const PointList& points, const Eigen::Vector3d& center_prior,
                            const FitParams& params, const Superellipsoid* initial = nullptr);

}  // namespace fruit_shape_completion
