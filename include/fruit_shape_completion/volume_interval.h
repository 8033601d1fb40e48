#pragma once
// How far to trust a fitted volume: a 90 % interval from the share of the fitted surface that
// was seen and how closely the fit explains its points. The interval is an empirical model: the
// 5th and 95th percentiles of true / fitted volume as a function of the seen share and the RMS
// residual, pooled over the fit stress suite (fit_stress, random
// fruits with noise, blur, outliers and touching neighbours) and scenario episodes; checked on
// another draw and other episodes (docs/benchmarks.md, "The volume interval").
#include <fruit_shape_completion/fruit_estimate.h>

namespace fruit_shape_completion {

struct VolumeInterval {
  double lo = 0.0, hi = 0.0;  // [m^3]
};

// The 90 % interval of a fitted `volume` whose surface was seen over `seen_share` of its samples.
// `rms`: the fit's RMS radial residual [m]. `size_at_bound`: the fit's shortest axis rests on
// the fit's lower bound (FitParams::min_axis).
VolumeInterval volumeInterval90(double volume, double seen_share, double rms, bool size_at_bound = false);

}  // namespace fruit_shape_completion
