#include <fruit_shape_completion/shape_targets.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace fruit_shape_completion {

void ShapeTargetParams::validate() const {
  if (!(settled_coverage >= 0.0 && settled_coverage <= 1.0))
    throw std::invalid_argument("target_settled_coverage must be in [0, 1], not " + std::to_string(settled_coverage));
  // At most the unseen samples a fruit can have (missing_surface_samples is at most 100 000).
  if (per_fruit < 0 || per_fruit > 100000)
    throw std::invalid_argument("targets_per_fruit must be in [0, 100000], not " + std::to_string(per_fruit));
  if (!(std::isfinite(offset) && offset >= 0.0 && offset <= 0.2))
    throw std::invalid_argument("target_offset must be in [0, 0.2] m, not " + std::to_string(offset));
  if (!(std::isfinite(view_gain) && view_gain >= 0.0 && view_gain <= 100.0))
    throw std::invalid_argument("target_view_gain must be in [0, 100], not " + std::to_string(view_gain));
  if (!(view_fov_deg > 0.0 && view_fov_deg < 180.0))
    throw std::invalid_argument("target_view_fov_deg must be in (0, 180), not " + std::to_string(view_fov_deg));
  if (!(std::isfinite(view_max_range) && view_max_range > 0.0))
    throw std::invalid_argument("target_view_max_range must be > 0 m, not " + std::to_string(view_max_range));
  if (!(std::isfinite(view_clearance) && view_clearance >= 0.0 && view_clearance <= kMaxViewClearance))
    throw std::invalid_argument("target_view_clearance must be in [0, 0.5] m, not " + std::to_string(view_clearance));
}

double seenCoverage(const FruitEstimate& fruit, int surface_samples) {
  return seenCoverage(fruit.missing_surface.size(), surface_samples);
}

double seenCoverage(std::size_t missing_samples, int surface_samples) {
  if (surface_samples <= 0) return 1.0;
  return std::clamp(1.0 - static_cast<double>(missing_samples) / surface_samples, 0.0, 1.0);
}

// By central differences of the implicit function: also where the closed form is singular (the
// exponents' poles and edges).
Eigen::Vector3d outwardNormal(const Superellipsoid& shape, const Point& s) {
  const double h = 1e-4;
  Eigen::Vector3d g;
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d[i] = h;
    g[i] = shape.implicit(s + d) - shape.implicit(s - d);
  }
  if (g.allFinite() && g.norm() > 1e-12) return g.normalized();
  const Eigen::Vector3d radial = s - shape.t;
  return radial.norm() > 1e-12 ? Eigen::Vector3d(radial.normalized()) : Eigen::Vector3d::UnitZ();
}

ShapeTargets selectShapeTargets(const std::vector<FruitEstimate>& fruits, int surface_samples,
                                const ShapeTargetParams& params) {
  ShapeTargets targets;
  if (params.view_gain > 0.0) {
    targets.view_cos_half_angle = std::cos(0.5 * params.view_fov_deg * M_PI / 180.0);
    targets.view_max_range = params.view_max_range;
    targets.view_clearance = params.view_clearance;
  }
  auto handsOver = [&](const FruitEstimate& f) {
    return f.accepted && !f.missing_surface.empty() &&
           !(params.settled_coverage < 1.0 && seenCoverage(f, surface_samples) >= params.settled_coverage);
  };
  auto kept = [&](const FruitEstimate& f) {
    const std::size_t n = f.missing_surface.size();
    return params.per_fruit > 0 ? std::min<std::size_t>(n, params.per_fruit) : n;
  };
  std::size_t total = 0;  // reserved once: the targets of a whole row are megabytes
  for (const auto& f : fruits) total += handsOver(f) ? kept(f) : 0;
  targets.points.reserve(total);
  targets.directions.reserve(total);
  if (params.view_gain > 0.0 && surface_samples > 0) targets.gains.reserve(total);
  for (const auto& f : fruits) {
    if (!handsOver(f)) continue;
    const std::size_t n = f.missing_surface.size();
    const std::size_t keep = kept(f);
    // Evenly strided: the samples come in surface-parameter order, so a stride spreads them.
    for (std::size_t i = 0; i < keep; ++i) {
      const std::size_t k = i * n / keep;
      const Point& s = f.missing_surface[k];
      const Eigen::Vector3d normal = f.missing_normals.size() == n ? f.missing_normals[k] : outwardNormal(f.shape, s);
      targets.points.push_back(s + params.offset * normal);
      targets.directions.push_back(params.view_side ? normal : Eigen::Vector3d::Zero());
      // Each kept target stands for n / keep of the fruit's samples.
      if (params.view_gain > 0.0 && surface_samples > 0)
        targets.gains.push_back(params.view_gain * static_cast<double>(n) / keep / surface_samples);
    }
  }
  return targets;
}

}  // namespace fruit_shape_completion
