#include <fruit_shape_completion/superellipsoid.h>

#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {

Superellipsoid Superellipsoid::sphere(double radius, const Eigen::Vector3d& center) {
  Superellipsoid s;
  s.a = s.b = s.c = radius;
  s.e1 = s.e2 = 1.0;
  s.t = center;
  return s;
}

Eigen::Matrix3d Superellipsoid::rotation() const {
  double r[9];
  rpyToRotation(rpy.data(), r);
  Eigen::Matrix3d R;
  R << r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8];
  return R;
}

Eigen::Vector3d Superellipsoid::toLocal(const Eigen::Vector3d& p_world) const {
  return rotation().transpose() * (p_world - t);
}

Eigen::Vector3d Superellipsoid::toWorld(const Eigen::Vector3d& p_local) const {
  return t + rotation() * p_local;
}

double Superellipsoid::implicitLocal(const Eigen::Vector3d& p) const {
  return superellipsoidImplicit(p.x(), p.y(), p.z(), a, b, c, e1, e2);
}

double Superellipsoid::radialDistance(const Eigen::Vector3d& p_world) const {
  const Eigen::Vector3d p = toLocal(p_world);
  const double r = p.norm();
  if (r < 1e-12) return std::min({a, b, c});  // at the centre: at least the smallest axis away
  return r * std::abs(1.0 - std::pow(implicitLocal(p), -e1 / 2.0));
}

Eigen::Vector3d Superellipsoid::surfacePointLocal(const Eigen::Vector3d& u) const {
  // f is homogeneous of degree 2/e1: f(s u) = s^(2/e1) f(u), so s = f(u)^(-e1/2).
  return u * std::pow(implicitLocal(u), -e1 / 2.0);
}

namespace {

// B(x, y) from tgamma: std::beta goes through lgamma, which writes the global signgam, a data
// race when fits run on several threads. The arguments here are small, far from overflow.
double betaFunction(double x, double y) { return std::tgamma(x) * std::tgamma(y) / std::tgamma(x + y); }

}  // namespace

double Superellipsoid::volume() const {
  return 2.0 * a * b * c * e1 * e2 * betaFunction(e1 / 2.0 + 1.0, e1) * betaFunction(e2 / 2.0, e2 / 2.0);
}

PointList Superellipsoid::sampleSurface(int n) const {
  PointList out;
  const PointList dirs = fibonacciSphere(n);
  out.reserve(dirs.size());
  const Eigen::Matrix3d R = rotation();
  for (const auto& u : dirs) out.push_back(t + R * surfacePointLocal(u));
  return out;
}

bool Superellipsoid::isFinite() const {
  return std::isfinite(a) && std::isfinite(b) && std::isfinite(c) && std::isfinite(e1) &&
         std::isfinite(e2) && t.allFinite() && rpy.allFinite();
}

PointList fibonacciSphere(int n) {
  PointList dirs;
  if (n <= 0) return dirs;
  dirs.reserve(n);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double phi = golden * i;
    dirs.emplace_back(r * std::cos(phi), r * std::sin(phi), z);
  }
  return dirs;
}

}  // namespace fruit_shape_completion
