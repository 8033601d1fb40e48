#include <fruit_shape_completion/volume_interval.h>

#include "seen_share_table.h"

#include <algorithm>

namespace fruit_shape_completion {

namespace {

// Seen share -> (5th, 95th percentile) of true / fitted volume, per class of the fit's RMS
// radial residual, pooled over the stress suite (1000 fruits, seed 1) and 80 paper-profile
// episodes of scenarios 1 and 2 (seeds 1-40) under the upstream-emulating planner with views
// scored by the predicted surface they see; a bin with fewer than 20 such fits keeps the values
// of the earlier pool (episodes of the planner without that score, which saw more fruits from
// one side). Made monotone (less seen or a larger residual, never narrower) and rounded
// outward. The residual separates what the seen share cannot: blurred depth and real capsicum
// shapes that no superellipsoid matches exactly leave 5-6 mm. The 5th percentiles at the knots
// (seen_share_table.h), per residual class, then the 95th:
constexpr double kLo[seen_share_table::kClasses][seen_share_table::kKnots] = {{0.60, 0.85, 0.85, 0.85, 0.85, 0.85, 0.86, 0.91},
                                                     {0.47, 0.60, 0.68, 0.73, 0.77, 0.81, 0.83, 0.83},
                                                     {0.32, 0.45, 0.60, 0.64, 0.64, 0.72, 0.74, 0.78}};
constexpr double kHi[seen_share_table::kClasses][seen_share_table::kKnots] = {{1.34, 1.34, 1.30, 1.30, 1.25, 1.16, 1.12, 1.07},
                                                     {1.80, 1.80, 1.30, 1.30, 1.25, 1.16, 1.14, 1.10},
                                                     {1.80, 1.80, 1.76, 1.76, 1.76, 1.16, 1.15, 1.15}};
// A fit whose shortest axis rests on its lower bound was sized by the bound, not by its points
// (a small patch of a larger fruit): its volume is nearly a floor. Pooled percentiles of such fits.
constexpr double kAtBoundLo = 0.80, kAtBoundHi = 3.0;

}  // namespace

VolumeInterval volumeInterval90(double volume, double seen_share, double rms, bool size_at_bound) {
  const int c = seen_share_table::residualClass(rms);
  double lo = seen_share_table::read(kLo[c], seen_share), hi = seen_share_table::read(kHi[c], seen_share);
  if (size_at_bound) {
    lo = std::min(lo, kAtBoundLo);
    hi = std::max(hi, kAtBoundHi);
  }
  return {lo * volume, hi * volume};
}

}  // namespace fruit_shape_completion
