#include <fruit_shape_completion/instrument/sim/analytic_depth_camera.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace fruit_shape_completion {

PinholeCamera PinholeCamera::lookingAt(const Eigen::Vector3d& position, const Eigen::Vector3d& target,
                                       int width, int height) {
  PinholeCamera cam;
  cam.width = width;
  cam.height = height;
  cam.position = position;
  const Eigen::Vector3d z = (target - position).normalized();
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  if (std::abs(z.dot(up)) > 0.99) up = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d x = z.cross(up).normalized();  // image right
  const Eigen::Vector3d y = z.cross(x);                // image down
  cam.rotation.col(0) = x;
  cam.rotation.col(1) = y;
  cam.rotation.col(2) = z;
  return cam;
}

double PinholeCamera::focalLength() const { return 0.5 * width / std::tan(0.5 * hfov_rad); }

Eigen::Vector3d PinholeCamera::rayDirection(int u, int v) const {
  return rotation * pixelPoint(u, v, 1.0, focalLength()).normalized();
}

namespace {

// First crossing into a superellipsoid along the ray: march inside its bounding box in steps of
// 2 mm (or a third of its thinnest axis), then bisect.
bool intersectSuperellipsoid(const Superellipsoid& se, const Eigen::Vector3d& o,
                             const Eigen::Vector3d& d, double t_min, double t_max, double* t_hit) {
  // The shape lies inside its box [-a, a] x [-b, b] x [-c, c]: clip the ray to it (slabs).
  const Eigen::Matrix3d Rt = se.rotation().transpose();
  const Eigen::Vector3d lo = Rt * (o - se.t), ld = Rt * d;
  const Eigen::Vector3d half(se.a, se.b, se.c);
  double t0 = t_min, t1 = t_max;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(ld[k]) < 1e-15) {
      if (std::abs(lo[k]) > half[k]) return false;
      continue;
    }
    double ta = (-half[k] - lo[k]) / ld[k], tb = (half[k] - lo[k]) / ld[k];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  auto inside = [&](double t) { return se.implicitLocal(lo + t * ld) <= 1.0; };
  if (inside(t0)) {
    *t_hit = t0;
    return true;
  }
  const double step = std::min(0.002, std::min({se.a, se.b, se.c}) / 3.0);
  for (double t = t0 + step; t <= t1 + step; t += step) {
    const double tc = std::min(t, t1);
    if (inside(tc)) {
      double lo_t = tc - step, hi_t = tc;
      for (int i = 0; i < 40; ++i) {
        const double mid = 0.5 * (lo_t + hi_t);
        (inside(mid) ? hi_t : lo_t) = mid;
      }
      *t_hit = hi_t;
      return true;
    }
    if (tc >= t1) break;
  }
  return false;
}

}  // namespace

int AnalyticScene::intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                             double t_max, double* t_hit) const {
  int best = -1;
  double best_t = t_max;
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    double t;
    if (intersectSuperellipsoid(shapes[i], o, d, t_min, best_t, &t) && t < best_t) {
      best_t = t;
      best = static_cast<int>(i);
    }
  }
  for (std::size_t i = 0; i < planes.size(); ++i) {
    const double den = planes[i].normal.dot(d);
    if (std::abs(den) < 1e-12) continue;
    const double t = planes[i].normal.dot(planes[i].point - o) / den;
    if (t >= t_min && t < best_t) {
      best_t = t;
      best = static_cast<int>(shapes.size() + i);
    }
  }
  if (best >= 0) *t_hit = best_t;
  return best;
}

DepthScan renderDepth(const AnalyticScene& scene, const PinholeCamera& camera, double noise_sigma,
                      std::uint32_t seed) {
  DepthScan scan;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (int v = 0; v < camera.height; ++v)
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d d = camera.rayDirection(u, v);
      double t;
      const int id = scene.intersect(camera.position, d, camera.min_range, camera.max_range, &t);
      if (id < 0) continue;
      if (noise_sigma > 0.0) t += noise_sigma * t * t * noise(rng);
      scan.points.push_back(camera.position + t * d);
      scan.labels.push_back(id);
    }
  return scan;
}

}  // namespace fruit_shape_completion
