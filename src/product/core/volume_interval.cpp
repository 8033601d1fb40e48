#include <fruit_shape_completion/volume_interval.h>

#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {

namespace {

// Seen share -> (5th, 95th percentile) of true / fitted volume, per class of the fit's RMS
// radial residual, pooled over the stress suite (1000 fruits, seed 1) and 80 paper-profile
// episodes of scenarios 1 and 2 (seeds 1-40) under the upstream-emulating planner with views
// scored by the predicted surface they see; a bin with fewer than 20 such fits keeps the values
// of the earlier pool (episodes of the planner without that score, which saw more fruits from
// one side). Made monotone (less seen or a larger residual, never narrower) and rounded
// outward. The residual separates what the seen share cannot: blurred depth and real capsicum
// shapes that no superellipsoid matches exactly leave 5-6 mm.
struct Knot {
  double seen, lo, hi;
};
constexpr int kKnotsPerClass = 8;
constexpr double kClassRms[] = {0.0035, 0.0055};  // upper RMS bounds of the first two classes [m]
constexpr Knot kKnots[3][kKnotsPerClass] = {
    {{0.45, 0.60, 1.34}, {0.55, 0.85, 1.34}, {0.65, 0.85, 1.30}, {0.75, 0.85, 1.30},
     {0.84, 0.85, 1.25}, {0.92, 0.85, 1.16}, {0.97, 0.86, 1.12}, {1.00, 0.91, 1.07}},
    {{0.45, 0.47, 1.80}, {0.55, 0.60, 1.80}, {0.65, 0.68, 1.30}, {0.75, 0.73, 1.30},
     {0.84, 0.77, 1.25}, {0.92, 0.81, 1.16}, {0.97, 0.83, 1.14}, {1.00, 0.83, 1.10}},
    {{0.45, 0.32, 1.80}, {0.55, 0.45, 1.80}, {0.65, 0.60, 1.76}, {0.75, 0.64, 1.76},
     {0.84, 0.64, 1.76}, {0.92, 0.72, 1.16}, {0.97, 0.74, 1.15}, {1.00, 0.78, 1.15}}};
// A fit whose shortest axis rests on its lower bound was sized by the bound, not by its points
// (a small patch of a larger fruit): its volume is nearly a floor. Pooled percentiles of such fits.
constexpr double kAtBoundLo = 0.80, kAtBoundHi = 3.0;

}  // namespace

VolumeInterval volumeInterval90(double volume, double seen_share, double rms, bool size_at_bound) {
  const double s = std::isfinite(seen_share) ? std::clamp(seen_share, 0.0, 1.0) : 0.0;
  const int c = !std::isfinite(rms) ? 2 : rms <= kClassRms[0] ? 0 : rms <= kClassRms[1] ? 1 : 2;
  const Knot* knots = kKnots[c];
  const int n = kKnotsPerClass;
  double lo = knots[0].lo, hi = knots[0].hi;
  if (s >= knots[n - 1].seen) {
    lo = knots[n - 1].lo, hi = knots[n - 1].hi;
  } else if (s > knots[0].seen) {
    for (int k = 1; k < n; ++k)
      if (s <= knots[k].seen) {
        const double f = (s - knots[k - 1].seen) / (knots[k].seen - knots[k - 1].seen);
        lo = knots[k - 1].lo + f * (knots[k].lo - knots[k - 1].lo);
        hi = knots[k - 1].hi + f * (knots[k].hi - knots[k - 1].hi);
        break;
      }
  }
  if (size_at_bound) {
    lo = std::min(lo, kAtBoundLo);
    hi = std::max(hi, kAtBoundHi);
  }
  return {lo * volume, hi * volume};
}

}  // namespace fruit_shape_completion
