#include <fruit_shape_completion/center_uncertainty.h>

#include "seen_share_table.h"

#include <algorithm>

namespace fruit_shape_completion {

namespace {

// Seen share -> 90th percentile of the distance from the fitted to the true centre [mm], per
// class of the RMS radial residual (the volume interval's classes), pooled over the fit stress
// suite (1000 fruits, seed 1) and 160 paper-profile episodes of scenarios 1 and 2 (seeds 1-40,
// with and without shape targets; one fit per true fruit, the nearest within 5 cm). A bin with
// fewer than 20 fits takes the class below's value (scripts/calibrate_center_radius.py makes the
// table); made monotone (less seen or a larger residual, never smaller) and rounded up to half a
// millimetre.
constexpr double kRadiusMm[seen_share_table::kClasses][seen_share_table::kKnots] = {{11.5, 9.0, 8.0, 7.5, 6.0, 4.0, 3.5, 2.5},
                                                           {20.0, 13.0, 13.0, 9.5, 8.0, 6.0, 5.0, 4.0},
                                                           {20.0, 17.5, 17.5, 17.5, 16.0, 11.5, 11.5, 6.5}};
// Fits whose shortest axis rests on its bound, pooled alike.
constexpr double kAtBoundMm = 19.0;

}  // namespace

double centerRadius90(double seen_share, double rms, bool size_at_bound) {
  double mm = seen_share_table::read(kRadiusMm[seen_share_table::residualClass(rms)], seen_share);
  if (size_at_bound) mm = std::max(mm, kAtBoundMm);
  return 1e-3 * mm;
}

}  // namespace fruit_shape_completion
