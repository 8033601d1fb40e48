#include <fruit_shape_completion/volume_interval.h>

#include <fruit_shape_completion/radial_residuals.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

namespace fruit_shape_completion {

namespace {

// The 5th and 95th percentiles of log(true / fitted volume) as linear functions of (1, log of the
// fit's log-volume spread, seen share, RMS radial residual beyond 3.5 mm, beyond 5.5 mm [mm], how
// few views saw it: log(kManyViews / views) when fewer), by linear quantile regression
// (scripts/calibrate_volume_interval.py) on a pool of groups that weigh alike: the stress suite
// with camera views (fit_stress --fruits 1000 --seed 1: synthetic superellipsoids and lobed
// peppers, each view cut at the fruit's silhouette as a camera sees it; clouds, so no view count),
// paper-profile episodes of scenarios 1 and 2 (real capsicum meshes; final fits of seeds 1-40,
// with and without shape targets), the same scenarios' fits after 60 and 120 s (seeds 1-20 with
// shape targets: fits a user reads before the run ends, seen in fewer views), and procedural:1
// and :2 (seeds 1-20; another fruit shape), all under the upstream-emulating planner. Each group
// alone misleads on the others: how closely a superellipsoid's volume matches a fully seen fruit
// depends on the fruit's shape family. Views cut at a plane through the fruit (the suite's caps)
// are not pooled: their fits err small more often than cameras'. The slopes' signs are held so that a larger spread or residual, or fewer
// views, never narrow the interval and more of the fruit seen never widens it. The spread says
// which fits the points pin down (a half-seen fruit whose depth they leave free); the residual
// what the spread cannot: blurred depth and shapes that no superellipsoid matches exactly; the
// views what neither can: each view's depth error is shared by all its points (the paper
// profile's structured noise), so a fruit seen in one or two views is as far off as that error,
// and more views average it out. Where the points leave the size free, or the residual is large,
// the interval reaches further above the fit than below (in ratio): the fit's size prior takes
// the smaller of the shapes such points leave alike, and fragments of a fruit fit small.
constexpr int kTerms = 6;
constexpr double kLo[kTerms] = {-0.4552, -0.0962, 0.0, -0.0251, -0.0024, -0.0936};
constexpr double kHi[kTerms] = {0.4881, 0.0903, 0.0, 0.0, 0.0198, 0.2558};
constexpr double kManyViews = 6.0;
constexpr double kRmsKneeMm[2] = {3.5, 5.5};
// The ranges the pool covers: the model reads its inputs clamped into them (below the smallest
// spread a straight line would leave the fit itself outside its interval).
constexpr double kSpreadMin = 0.01, kSpreadMax = 0.5, kRmsMinMm = 1.0, kRmsMaxMm = 8.0;
// A fit whose shortest axis rests on its lower bound was sized by the bound, not by its points
// (a small patch of a larger fruit): its volume is nearly a floor. Pooled percentiles of such fits.
constexpr double kAtBoundLo = 0.89, kAtBoundHi = 3.5;

}  // namespace

double logVolumeSpread(const PointList& points, const Superellipsoid& shape) {
  constexpr int kParams = 11;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  PointList finite;
  finite.reserve(points.size());
  for (const auto& p : points)
    if (p.allFinite()) finite.push_back(p);
  // The spread shrinks as the square root of the points it is taken on: always on the same
  // number, the one the model was calibrated with, whatever the fit's own max_points.
  const PointList used = evenlyStrided(finite, kSpreadPoints);
  if (used.size() <= static_cast<std::size_t>(kParams) || !shape.isFinite()) return nan;
  Eigen::VectorXd residuals;
  Eigen::MatrixXd J;
  evaluateRadialResiduals(used, shape, &residuals, &J);
  // No fit the model was made from explained its points closer than 1.75 mm RMS (a 4 mm TSDF
  // surface never lies closer to the true one): a cleaner cloud, a mesh say, must not read as
  // more certain than any of them, so the residual's spread is held at least there.
  constexpr double kMinSigma = 0.00175;
  const double variance =
      std::max(kMinSigma * kMinSigma, residuals.squaredNorm() / static_cast<double>(used.size() - kParams));
  Eigen::Matrix<double, kParams, kParams> H = J.transpose() * J;
  // A parameter the points do not move at all (an exponent along a flat patch) would make H
  // singular: a tiny ridge leaves it very uncertain instead of undefined.
  H.diagonal().array() += 1e-9 * H.diagonal().maxCoeff();
  // d log V / d parameter: 1/a, 1/b, 1/c, the exponents' numerically; the pose does not enter.
  Eigen::Matrix<double, kParams, 1> g = Eigen::Matrix<double, kParams, 1>::Zero();
  g(0) = 1.0 / shape.a;
  g(1) = 1.0 / shape.b;
  g(2) = 1.0 / shape.c;
  const double h = 1e-5;
  for (int k = 0; k < 2; ++k) {
    Superellipsoid up = shape, down = shape;
    (k == 0 ? up.e1 : up.e2) += h;
    (k == 0 ? down.e1 : down.e2) -= h;
    g(3 + k) = (std::log(up.volume()) - std::log(down.volume())) / (2.0 * h);
  }
  const double spread2 = variance * g.dot(H.ldlt().solve(g));
  return std::isfinite(spread2) && spread2 >= 0.0 ? std::sqrt(spread2) : nan;
}

VolumeInterval volumeInterval90(double volume, double seen_share, double rms, double log_volume_spread,
                                bool size_at_bound, int views) {
  // Nonsense reads as the least favourable: nothing seen, the largest spread and residual.
  const double spread =
      std::isfinite(log_volume_spread) ? std::clamp(log_volume_spread, kSpreadMin, kSpreadMax) : kSpreadMax;
  const double seen = std::isfinite(seen_share) ? std::clamp(seen_share, 0.0, 1.0) : 0.0;
  const double rms_mm = std::isfinite(rms) ? std::clamp(1e3 * rms, kRmsMinMm, kRmsMaxMm) : kRmsMaxMm;
  // Not counted (a cloud given whole) reads as the suite's clouds, calibrated without a count; a
  // negative count as one view.
  const double few_views = views == 0 ? 0.0 : std::max(0.0, std::log(kManyViews / std::max(1, views)));
  const double x[kTerms] = {1.0, std::log(spread), seen, std::max(0.0, rms_mm - kRmsKneeMm[0]),
                            std::max(0.0, rms_mm - kRmsKneeMm[1]), few_views};
  double log_lo = 0.0, log_hi = 0.0;
  for (int k = 0; k < kTerms; ++k) {
    log_lo += kLo[k] * x[k];
    log_hi += kHi[k] * x[k];
  }
  double lo = std::exp(log_lo), hi = std::exp(log_hi);
  if (size_at_bound) {
    lo = std::min(lo, kAtBoundLo);
    hi = std::max(hi, kAtBoundHi);
  }
  return {lo * volume, hi * volume};
}

VolumeInterval volumeInterval90(const FruitEstimate& fruit) {
  return volumeInterval90(fruit.volume, fruit.seen_share, fruit.rms, fruit.log_volume_spread, fruit.size_at_bound,
                          fruit.views);
}

}  // namespace fruit_shape_completion
