#pragma once
// The predicted, not yet seen part of a fruit: samples of the fitted surface with no observed
// point within `threshold`. These become the planner's extra ROI targets.
#include <fruit_shape_completion/superellipsoid.h>

namespace fruit_shape_completion {

struct MissingSurfaceParams {
  int samples = 300;         // surface samples per fruit
  double threshold = 0.015;  // [m]
};

PointList predictMissingSurface(const Superellipsoid& shape, const PointList& observed,
                                const MissingSurfaceParams& params);

}  // namespace fruit_shape_completion
