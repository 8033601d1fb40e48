#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>

#include <Eigen/Geometry>
#include <cmath>
#include <unordered_set>

#include <fruit_shape_completion/grid_cell.h>

namespace fruit_shape_completion {

Eigen::Vector3d SyntheticFruit::surfacePoint(const Eigen::Vector3d& u) const {
  return center + rotation * (u * radius(u));
}

double SyntheticFruit::volume(int samples) const {
  double sum = 0.0;
  for (const auto& u : fibonacciSphere(samples)) sum += std::pow(radius(u), 3) / 3.0;
  return sum * 4.0 * M_PI / samples;
}

Eigen::Vector3d SyntheticFruit::centroid(int samples) const {
  // Solid cone of direction u: volume r^3/3 dOmega, its centroid at 3/4 r u.
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
  double vol = 0.0;
  for (const auto& u : fibonacciSphere(samples)) {
    const double r = radius(u);
    vol += r * r * r / 3.0;
    moment += u * (r * r * r * r / 4.0);
  }
  return center + rotation * (moment / vol);
}

SyntheticFruit SyntheticFruit::fromSuperellipsoid(const Superellipsoid& se) {
  SyntheticFruit f;
  f.center = se.t;
  f.rotation = se.rotation();
  Superellipsoid local = se;
  local.t.setZero();
  local.rpy.setZero();
  f.radius = [local](const Eigen::Vector3d& u) { return local.surfacePointLocal(u).norm(); };
  return f;
}

SyntheticFruit SyntheticFruit::pepper(double r, double h, int lobes, double lobe_depth,
                                      double taper, const Eigen::Vector3d& center,
                                      const Eigen::Matrix3d& rotation) {
  SyntheticFruit f;
  f.center = center;
  f.rotation = rotation;
  f.radius = [=](const Eigen::Vector3d& u) {
    // A squarish body (superellipsoid-like exponent 0.7 in elevation) ...
    const double theta = std::acos(std::max(-1.0, std::min(1.0, u.z())));  // from the top
    const double phi = std::atan2(u.y(), u.x());
    const double s = std::sin(theta), c = std::cos(theta);
    const double e = 0.7;
    const double body = 1.0 / std::pow(std::pow(std::abs(s) / r, 2.0 / e) +
                                            std::pow(std::abs(c) / h, 2.0 / e),
                                        e / 2.0);
    // ... with lobes that fade toward the bottom tip, a taper, and a dent at the stem.
    const double lobe = 1.0 + lobe_depth * std::cos(lobes * phi) * std::pow(s, 2.0);
    const double tap = 1.0 - taper * 0.5 * (1.0 - c) * s;
    const double dent = 1.0 - 0.12 * std::exp(-std::pow(theta / 0.35, 2.0));
    return body * lobe * tap * dent;
  };
  return f;
}

PointList scanFruit(const SyntheticFruit& fruit, const ScanParams& params) {
  std::mt19937 rng(params.seed);
  std::normal_distribution<double> noise(0.0, params.noise_sigma);
  const Eigen::Vector3d view = params.view_dir.normalized();
  const double min_dot = 1.0 - 2.0 * params.visible_fraction;
  // Dense enough that every voxel the surface passes through gets a sample.
  double mean_r = 0.0;
  const PointList probe = fibonacciSphere(64);
  for (const auto& u : probe) mean_r += fruit.radius(u) / probe.size();
  const double area = 4.0 * M_PI * mean_r * mean_r;
  const double cell = params.voxel > 0.0 ? params.voxel : 0.002;
  const int n = static_cast<int>(std::min(2.0e6, std::max(2.0e4, 60.0 * area / (cell * cell))));

  PointList out;
  std::unordered_set<std::uint64_t> seen;
  for (const auto& u : fibonacciSphere(n)) {
    const Eigen::Vector3d p = fruit.surfacePoint(u);
    if ((p - fruit.center).normalized().dot(view) < min_dot) continue;
    Eigen::Vector3d q = p;
    if (params.voxel > 0.0) {
      const GridCell cell = cellOf(p, 1.0 / params.voxel);
      if (!seen.insert(packCellKey(cell)).second) continue;
      q = (cell.cast<double>().array() + 0.5) * params.voxel;
    }
    if (params.noise_sigma > 0.0) q += Eigen::Vector3d{noise(rng), noise(rng), noise(rng)};
    out.push_back(q);
  }
  return out;
}

Eigen::Matrix3d randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::Quaterniond q{g(rng), g(rng), g(rng), g(rng)};  // braces: drawn left to right
  q.normalize();
  return q.toRotationMatrix();
}

Superellipsoid randomSuperellipsoid(std::mt19937& rng, const Eigen::Vector3d& center,
                                    const RandomShapeRange& range) {
  std::uniform_real_distribution<double> radius(range.min_radius, range.max_radius);
  std::uniform_real_distribution<double> factor(-std::log(range.aspect), std::log(range.aspect));
  std::uniform_real_distribution<double> ex(range.min_e, range.max_e);
  Superellipsoid se;
  const double r = radius(rng);
  se.a = r * std::exp(factor(rng));
  se.b = r * std::exp(factor(rng));
  se.c = r * std::exp(factor(rng));
  se.e1 = ex(rng);
  se.e2 = ex(rng);
  se.t = center;
  const Eigen::Matrix3d R = randomRotation(rng);
  // rpy of R in this package's convention (R = Rz(yaw) Ry(pitch) Rx(roll)).
  se.rpy = Eigen::Vector3d(std::atan2(R(2, 1), R(2, 2)), std::asin(-std::max(-1.0, std::min(1.0, R(2, 0)))),
                           std::atan2(R(1, 0), R(0, 0)));
  return se;
}

}  // namespace fruit_shape_completion
