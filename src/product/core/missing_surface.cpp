#include <fruit_shape_completion/missing_surface.h>
#include <fruit_shape_completion/neighbour_grid.h>

namespace fruit_shape_completion {

// A NeighbourGrid, not a kd-tree: the fruit's points are indexed afresh at every refit and
// queried once per sample, and a grid is built in a sort (docs/benchmarks.md).
PointList predictMissingSurface(const Superellipsoid& shape, const PointList& observed,
                                const MissingSurfaceParams& params) {
  PointList missing;
  const NeighbourGrid grid(observed, params.threshold);
  for (const auto& s : shape.sampleSurface(params.samples))
    if (s.allFinite() && !grid.anyWithin(s, params.threshold)) missing.push_back(s);
  return missing;
}

}  // namespace fruit_shape_completion
