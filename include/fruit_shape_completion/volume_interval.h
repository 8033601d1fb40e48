#pragma once
// How far to trust a fitted volume: a 90 % interval from how far the fit's points pin its size
// down (the log-volume spread), the share of the fitted surface that was seen, how closely the
// fit explains its points and how many views saw the fruit. The interval is an empirical model:
// the 5th and 95th percentiles of true / fitted volume as functions of these, pooled over the fit
// stress suite (fit_stress, random fruits as cameras see them, with noise, blur, outliers and
// touching neighbours), scenario episodes (their final fits and those after 60 and 120 s) and
// procedural scenes; checked on another draw and other episodes (docs/benchmarks.md, "The volume
// interval reads the views").
#include <fruit_shape_completion/fruit_estimate.h>

namespace fruit_shape_completion {

struct VolumeInterval {
  double lo = 0.0, hi = 0.0;  // [m^3]
};

// The points logVolumeSpread is taken on (at most; evenly strided from the finite ones).
constexpr int kSpreadPoints = 300;

// The standard deviation of log(volume) implied by the fit's data alone, to first order: the
// residual variance times the inverse Gauss-Newton matrix of the radial residuals over the 11
// parameters (on kSpreadPoints of the points), carried through the volume's derivatives, the
// residual taken as at least 1.75 mm RMS. It is not an uncertainty by itself (it leaves out the
// shape's own mismatch), but it says which fits the data pins down: a half-seen fruit whose
// depth the points leave free gets a large one. Non-finite when it cannot be computed (fewer
// than 12 finite points).
double logVolumeSpread(const PointList& points, const Superellipsoid& shape);

// The 90 % interval of a fitted `volume` whose surface was seen over `seen_share` of its samples.
// `rms`: the fit's RMS radial residual [m]. `log_volume_spread`: logVolumeSpread of the fit.
// `size_at_bound`: the fit's shortest axis rests on the fit's lower bound (FitParams::min_axis).
// `views`: the views a fused map's fruit was seen in (0: not counted, a cloud given whole). Each
// view of a real camera brings its own depth error, which its points share and the residuals
// cannot show; a fruit seen in few views keeps it, so its interval is wider.
// Non-finite inputs read as the least favourable values.
VolumeInterval volumeInterval90(double volume, double seen_share, double rms, double log_volume_spread,
                                bool size_at_bound = false, int views = 0);

// The interval of an estimate from what it records (its volume, seen_share, rms,
// log_volume_spread, size_at_bound and views).
VolumeInterval volumeInterval90(const FruitEstimate& fruit);

}  // namespace fruit_shape_completion
