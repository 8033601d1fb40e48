#pragma once
// The predicted, not yet seen part of a fruit: samples of the fitted surface with no observed
// point within `threshold`. These become the planner's extra ROI targets.
#include <fruit_shape_completion/spatial_hash_grid.h>
#include <fruit_shape_completion/superellipsoid.h>

namespace fruit_shape_completion {

struct MissingSurfaceParams {
  int samples = 300;        // surface samples per fruit
  double threshold = 0.015;  // [m]
};

// `observed` is a grid over the fruit's observed points with cell size >= threshold.
PointList predictMissingSurface(const Superellipsoid& shape, const SpatialHashGrid& observed,
                                const MissingSurfaceParams& params);

}  // namespace fruit_shape_completion
