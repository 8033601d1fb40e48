#pragma once
// A pinhole depth camera over analytic shapes (superellipsoids, incl. spheres, and planes):
// exact ray hits for tests and benchmarks of the TSDF map, no mesh or ray tracer needed.
#include <fruit_shape_completion/superellipsoid.h>

#include <cstdint>
#include <vector>

namespace fruit_shape_completion {

struct PinholeCamera {
  int width = 640, height = 480;
  double hfov_rad = 80.0 * M_PI / 180.0;
  double min_range = 0.15, max_range = 3.0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // camera -> world; camera z forward, x right, y down

  // Looks from `position` at `target`, world z up in the image.
  static PinholeCamera lookingAt(const Eigen::Vector3d& position, const Eigen::Vector3d& target,
                                 int width = 640, int height = 480);
  // World-frame unit ray through the centre of pixel (u, v).
  Eigen::Vector3d rayDirection(int u, int v) const;
  // The focal length in pixels (square pixels, principal point at the image centre).
  double focalLength() const;
  // The camera-frame point seen at the centre of pixel (u, v) at depth z along the optical axis;
  // `focal` is focalLength(), passed in so that a loop over the pixels computes it once.
  Eigen::Vector3d pixelPoint(int u, int v, double z, double focal) const {
    return {(u + 0.5 - 0.5 * width) / focal * z, (v + 0.5 - 0.5 * height) / focal * z, z};
  }
};

struct AnalyticScene {
  std::vector<Superellipsoid> shapes;
  struct Plane {
    Eigen::Vector3d point, normal;
  };
  std::vector<Plane> planes;

  // Nearest hit along a ray (t in [t_min, t_max]); returns the shape index (planes after shapes),
  // or -1 for no hit.
  int intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_min,
                double t_max, double* t_hit) const;
};

struct DepthScan {
  PointList points;         // world frame, one per pixel with a hit
  std::vector<int> labels;  // which shape (index into scene.shapes; planes after them)
};

// Gaussian noise along the ray with sigma = noise_sigma (at 1 m) times range^2 (0: exact hits).
DepthScan renderDepth(const AnalyticScene& scene, const PinholeCamera& camera,
                      double noise_sigma = 0.0, std::uint32_t seed = 1);

}  // namespace fruit_shape_completion
