#pragma once
// Synthetic fruits with known truth, for tests, benchmarks and the demo: star-shaped solids
// (a superellipsoid, or a lobed, tapered pepper-like shape that is NOT a superellipsoid)
// scanned as a TSDF map would deliver them: surface quantised to voxel centres, noise added,
// only part of the surface seen.
#include <fruit_shape_completion/superellipsoid.h>

#include <cstdint>
#include <functional>
#include <random>

namespace fruit_shape_completion {

struct SyntheticFruit {
  // Distance from the centre to the surface along a unit direction of the local frame.
  std::function<double(const Eigen::Vector3d&)> radius;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();

  Eigen::Vector3d surfacePoint(const Eigen::Vector3d& unit_local) const;
  // Enclosed volume, integrating r^3 / 3 over the sphere of directions.
  double volume(int samples = 200000) const;
  // Centroid of the enclosed solid (world frame).
  Eigen::Vector3d centroid(int samples = 200000) const;

  static SyntheticFruit fromSuperellipsoid(const Superellipsoid& se);
  // A bell-pepper-like solid: an ellipsoid-ish body of radius `r` and half height `h`, with
  // `lobes` bumps of relative depth `lobe_depth` around its axis, narrower at the bottom by
  // `taper`, and a shallow dent at the stem.
  static SyntheticFruit pepper(double r, double h, int lobes, double lobe_depth, double taper,
                               const Eigen::Vector3d& center, const Eigen::Matrix3d& rotation);
};

struct ScanParams {
  double voxel = 0.004;        // surface snapped to centres of this grid (0: no quantisation)
  double noise_sigma = 0.001;  // Gaussian noise per coordinate [m]
  double visible_fraction = 1.0;  // part of the surface seen: a cap around view_dir
  Eigen::Vector3d view_dir = Eigen::Vector3d::UnitX();  // from the centre toward the viewer
  std::uint32_t seed = 1;
};

PointList scanFruit(const SyntheticFruit& fruit, const ScanParams& params);

// The range of random fruit-like superellipsoids: a mean radius, each axis that radius times a
// factor in [1/aspect, aspect], exponents in [min_e, max_e], uniformly random rotation. The
// defaults span sweet peppers of about 60 to 700 cm^3.
struct RandomShapeRange {
  double min_radius = 0.03, max_radius = 0.05;  // [m]
  double aspect = 1.25;
  double min_e = 0.4, max_e = 0.85;
};
Superellipsoid randomSuperellipsoid(std::mt19937& rng, const Eigen::Vector3d& center,
                                    const RandomShapeRange& range = RandomShapeRange());

Eigen::Matrix3d randomRotation(std::mt19937& rng);

}  // namespace fruit_shape_completion
