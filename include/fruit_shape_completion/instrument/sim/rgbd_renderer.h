#pragma once
// A simulated RGB-D camera: Embree ray casting of a scene's triangles through a pinhole
// camera (640x480, 80 degree horizontal field of view, 0.15-3 m by default), colour from the
// material (flat, or its texture as Gazebo draws it), per-pixel ground-truth labels, and an
// optional depth noise model.
#include <fruit_shape_completion/fruit_input_stage.h>
#include <fruit_shape_completion/instrument/sim/analytic_depth_camera.h>
#include <fruit_shape_completion/instrument/sim/scene.h>

#include <cstdint>
#include <memory>
#include <vector>

namespace fruit_shape_completion {
namespace sim {

struct DepthNoise {
  bool enabled = true;
  enum class Model {
    // Independent per pixel: sigma(z) = base + quad * (z - ref)^2 (Nguyen et al. 2012, Kinect),
    // no depth beyond max_incidence_deg.
    kIndependent,
    // The paper's simulation, applied to the noise-free depth image: sums of sinusoids over the
    // image (additive 2, 1.5, 1 mm; multiplicative 0.2 %, 0.7 %), a 3x3 Gaussian blur (edges
    // blur into mixed depths), then Gaussian noise of paper_sigma_base + paper_sigma_rel * z.
    kPaper,
  };
  Model model = Model::kIndependent;
  double base = 0.0012, quad = 0.0019, ref = 0.4;
  double max_incidence_deg = 80.0;
  double paper_sigma_base = 0.001, paper_sigma_rel = 0.003;
  std::uint32_t seed = 1;
};

// How surfaces are coloured. Flat (the ideal simulation): the material's colour, lit from the
// camera. Textured (the paper's Gazebo): the mesh's texture at the hit's texture coordinates,
// the surface cut where the texture's alpha is below one half (leaf outlines), lit by an
// ambient term and one directional light (Lambert); the defaults are Gazebo's default scene
// ambient and sun. Materials without a texture keep their flat colour under the same light.
struct Shading {
  bool textures = false;
  Eigen::Vector3d light_direction = Eigen::Vector3d(-0.5, 0.1, -0.9);  // where the light travels
  double ambient = 0.4, diffuse = 0.8;
};

struct RgbdFrame {
  PinholeCamera camera;
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // 3 bytes per pixel, row-major
  std::vector<float> depth;       // along the optical axis [m]; NaN where invalid
  std::vector<int> material;      // per pixel: material index of the hit, -1 for none
  std::vector<int> fruit;         // per pixel: ground-truth fruit id, -1 for none
};

struct FrameClouds {
  PointList fruit;  // masked pixels with valid depth, world frame
  PointList full;   // all pixels with valid depth, world frame
};

class RgbdRenderer {
 public:
  // `triangle_fruit`: per scene triangle, the fruit id (computeFruitTruth) or -1; may be empty.
  // Throws std::invalid_argument for a vertex that is not finite or beyond kMaxCoordinate, a bad
  // index or material (loadScene refuses such files before).
  RgbdRenderer(const Scene& scene, std::vector<int> triangle_fruit, const Shading& shading = Shading());
  ~RgbdRenderer();
  RgbdRenderer(const RgbdRenderer&) = delete;
  RgbdRenderer& operator=(const RgbdRenderer&) = delete;

  // Renders one frame; `threads` rows-interleaved worker threads (1 or more). Throws
  // std::invalid_argument for a pose that is not finite or beyond kMaxCoordinate.
  RgbdFrame render(const PinholeCamera& camera, const DepthNoise& noise = DepthNoise(), int threads = 2) const;

  // True if no geometry lies within `radius` of p (26 probe rays): a camera may stand there.
  bool isClear(const Eigen::Vector3d& p, double radius) const;
  // Distance to the first hit along a ray, or infinity (also for a ray that is not finite);
  // textured, rays pass through the cut-away parts of leaves.
  double castRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_range) const;

  struct Impl;  // the ray tracer's state (public for its hit filter callback)

 private:
  std::unique_ptr<Impl> impl_;
};

// Back-projects a frame's valid depth pixels: all of them, and those where mask is non-zero.
// `full_pixels`, if given, receives the pixel index of each point of the full cloud.
FrameClouds cloudsFromFrame(const RgbdFrame& frame, const std::vector<std::uint8_t>& mask,
                            std::vector<std::size_t>* full_pixels = nullptr);

// The frame as a camera driver publishes it (depth_image_proc's point_cloud_xyzrgb): organized
// XYZRGB in the camera's optical frame, NaN where there is no depth. What the product's input
// stage gets from a real camera.
OrganizedFrame organizedFrame(const RgbdFrame& frame);
// The camera's pose (camera -> world) as a robot's tf gives it.
Eigen::Isometry3d cameraPose(const PinholeCamera& camera);

}  // namespace sim
}  // namespace fruit_shape_completion
