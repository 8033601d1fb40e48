#include <fruit_shape_completion/missing_surface.h>

namespace fruit_shape_completion {

PointList predictMissingSurface(const Superellipsoid& shape, const SpatialHashGrid& observed,
                                const MissingSurfaceParams& params) {
  PointList missing;
  for (const auto& s : shape.sampleSurface(params.samples))
    if (s.allFinite() && !observed.anyWithin(s, params.threshold)) missing.push_back(s);
  return missing;
}

}  // namespace fruit_shape_completion
