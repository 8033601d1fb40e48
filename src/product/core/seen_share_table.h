#pragma once
// The columns the volume interval (volume_interval.cpp) and the centre radius
// (center_uncertainty.cpp) share: their tables are read at the same seen-share knots, per the
// same classes of the fit's RMS radial residual (scripts/calibrate_center_radius.py uses them too).
#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {
namespace seen_share_table {

constexpr int kKnots = 8;
constexpr double kSeen[kKnots] = {0.45, 0.55, 0.65, 0.75, 0.84, 0.92, 0.97, 1.00};
constexpr int kClasses = 3;
constexpr double kClassRms[kClasses - 1] = {0.0035, 0.0055};  // upper RMS bounds of the first two classes [m]

// The class of an RMS residual [m]; a non-finite one is the last.
inline int residualClass(double rms) {
  return !std::isfinite(rms) ? 2 : rms <= kClassRms[0] ? 0 : rms <= kClassRms[1] ? 1 : 2;
}

// `values` (one per knot) at `seen_share`: linear between knots, the end values beyond them; a
// non-finite share reads as nothing seen.
inline double read(const double* values, double seen_share) {
  const double s = std::isfinite(seen_share) ? std::clamp(seen_share, 0.0, 1.0) : 0.0;
  if (s >= kSeen[kKnots - 1]) return values[kKnots - 1];
  if (s > kSeen[0])
    for (int k = 1; k < kKnots; ++k)
      if (s <= kSeen[k]) return values[k - 1] + (s - kSeen[k - 1]) / (kSeen[k] - kSeen[k - 1]) * (values[k] - values[k - 1]);
  return values[0];
}

}  // namespace seen_share_table
}  // namespace fruit_shape_completion
