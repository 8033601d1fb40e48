#include <fruit_shape_completion/volume_interval.h>

#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {

namespace {

// Seen share -> (5th, 95th percentile) of true / fitted volume on the stress suite, made
// monotone (less seen, never narrower) and rounded outward.
struct Knot {
  double seen, lo, hi;
};
constexpr Knot kKnots[] = {{0.45, 0.60, 1.30}, {0.55, 0.74, 1.30}, {0.65, 0.85, 1.33}, {0.75, 0.86, 1.30},
                           {0.85, 0.87, 1.28}, {0.92, 0.87, 1.25}, {0.97, 0.89, 1.12}, {1.00, 0.89, 1.10}};

}  // namespace

VolumeInterval volumeInterval90(double volume, double seen_share) {
  const double s = std::isfinite(seen_share) ? std::clamp(seen_share, 0.0, 1.0) : 0.0;
  const std::size_t n = sizeof(kKnots) / sizeof(kKnots[0]);
  double lo = kKnots[0].lo, hi = kKnots[0].hi;
  if (s >= kKnots[n - 1].seen) {
    lo = kKnots[n - 1].lo, hi = kKnots[n - 1].hi;
  } else if (s > kKnots[0].seen) {
    for (std::size_t k = 1; k < n; ++k)
      if (s <= kKnots[k].seen) {
        const double f = (s - kKnots[k - 1].seen) / (kKnots[k].seen - kKnots[k - 1].seen);
        lo = kKnots[k - 1].lo + f * (kKnots[k].lo - kKnots[k - 1].lo);
        hi = kKnots[k - 1].hi + f * (kKnots[k].hi - kKnots[k - 1].hi);
        break;
      }
  }
  return {lo * volume, hi * volume};
}

}  // namespace fruit_shape_completion
