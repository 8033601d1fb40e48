#pragma once
// How far to trust a fitted centre: the radius around it that holds the true centre in 90 % of
// fits alike in the share of their surface that was seen and in their RMS residual. An empirical
// table, pooled from the stress suite and scenario episodes as the volume interval
// (volume_interval.h) is: the solver's own covariance of the centre comes out about five times
// too small, since what moves a half-seen fruit's centre is its shape and the prior, not
// independent noise (docs/benchmarks.md, "A centre uncertainty"; the current table: "A pull
// toward smaller shapes").
namespace fruit_shape_completion {

// [m]. `seen_share`: the fit's seen share (shape_targets.h seenCoverage); `rms`: its RMS radial
// residual [m]; `size_at_bound`: its shortest axis rests on FitParams::min_axis (a small patch of
// a larger fruit, placed by its points only roughly).
double centerRadius90(double seen_share, double rms, bool size_at_bound = false);

}  // namespace fruit_shape_completion
