#include <fruit_shape_completion/center_uncertainty.h>

#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {

namespace {

// The table's columns: seen-share knots, and classes of the fit's RMS radial residual
// (scripts/calibrate_center_radius.py uses the same).
constexpr int kKnots = 8;
constexpr double kSeen[kKnots] = {0.45, 0.55, 0.65, 0.75, 0.84, 0.92, 0.97, 1.00};
constexpr int kClasses = 3;
constexpr double kClassRms[kClasses - 1] = {0.0035, 0.0055};  // upper RMS bounds of the first two classes [m]

// The class of an RMS residual [m]; a non-finite one is the last.
int residualClass(double rms) {
  return !std::isfinite(rms) ? 2 : rms <= kClassRms[0] ? 0 : rms <= kClassRms[1] ? 1 : 2;
}

// `values` (one per knot) at `seen_share`: linear between knots, the end values beyond them; a
// non-finite share reads as nothing seen.
double read(const double* values, double seen_share) {
  const double s = std::isfinite(seen_share) ? std::clamp(seen_share, 0.0, 1.0) : 0.0;
  if (s >= kSeen[kKnots - 1]) return values[kKnots - 1];
  if (s > kSeen[0])
    for (int k = 1; k < kKnots; ++k)
      if (s <= kSeen[k]) return values[k - 1] + (s - kSeen[k - 1]) / (kSeen[k] - kSeen[k - 1]) * (values[k] - values[k - 1]);
  return values[0];
}

// Seen share -> 90th percentile of the distance from the fitted to the true centre [mm], per
// class of the RMS radial residual, pooled over the fit stress suite with camera views (1000
// fruits, seed 1) and 160 paper-profile episodes of scenarios 1 and 2 (seeds 1-40, with and
// without shape targets; one fit per true fruit, the nearest within 5 cm). A bin with fewer than 20 fits takes the
// class below's value (scripts/calibrate_center_radius.py makes the table); made monotone (less
// seen or a larger residual, never smaller) and rounded up to half a millimetre.
constexpr double kRadiusMm[kClasses][kKnots] = {{13.0, 8.0, 4.5, 4.0, 4.0, 4.0, 3.5, 2.5},
                                                {14.5, 14.5, 11.0, 7.5, 6.5, 5.5, 4.5, 4.0},
                                                {18.5, 18.5, 18.5, 18.5, 13.5, 11.5, 11.5, 6.0}};
// Fits whose shortest axis rests on its bound, pooled alike.
constexpr double kAtBoundMm = 20.5;

}  // namespace

double centerRadius90(double seen_share, double rms, bool size_at_bound) {
  double mm = read(kRadiusMm[residualClass(rms)], seen_share);
  if (size_at_bound) mm = std::max(mm, kAtBoundMm);
  return 1e-3 * mm;
}

}  // namespace fruit_shape_completion
