#pragma once
// How far to trust a fitted volume: a 90 % interval from the share of the fitted surface that
// was seen. The interval is an empirical model: the 5th and 95th percentiles of true / fitted
// volume on the fit stress suite (fit_stress, 1000 random fruits with noise, blur, outliers and
// touching neighbours, seed 1), as a function of the seen share; checked on another draw and
// on the scenario episodes (docs/benchmarks.md, "The volume interval").
#include <fruit_shape_completion/fruit_estimate.h>

namespace fruit_shape_completion {

struct VolumeInterval {
  double lo = 0.0, hi = 0.0;  // [m^3]
};

// The 90 % interval of a fitted `volume` whose surface was seen over `seen_share` of its samples.
VolumeInterval volumeInterval90(double volume, double seen_share);

}  // namespace fruit_shape_completion
