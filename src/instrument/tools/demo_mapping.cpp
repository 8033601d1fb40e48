// demo_mapping: the core of the method end to end on an analytic scene: a depth camera moves
// around a cluster of fruits (superellipsoids) partly hidden by leaves; after every view the
// fruit pixels go into the TSDF map, its surface is clustered and fitted, and the table shows
// how the volume estimates converge as more of each fruit is seen.
//   demo_mapping [--seed N] [--views N] [--save-map FILE.tsdf]
#include <fruit_shape_completion/instrument/sim/analytic_depth_camera.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>
#include <fruit_shape_completion/tsdf_integrator.h>
#include <fruit_shape_completion/tsdf_surface.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include "command_line.h"

#include <iostream>
#include <string>

using namespace fruit_shape_completion;

int main(int argc, char** argv) {
  unsigned seed = 3;
  int views = 8;
  std::string save_map;
  CLI::App app("Maps a simulated fruit cluster from several views and fits its fruits.", "demo_mapping");
  app.add_option("--seed", seed, "random seed")->capture_default_str();
  app.add_option("--views", views, "views of the cluster")->check(CLI::Range(1, 100))->capture_default_str();
  app.add_option("--save-map", save_map, "write the TSDF map to FILE.tsdf");
  if (const int done = parseCommandLine(app, argc, argv); done >= 0) return done;
  std::mt19937 rng(seed);
  const Eigen::Vector3d plant(0.0, 0.6, 0.5);
  AnalyticScene scene;
  std::uniform_real_distribution<double> u(-1, 1);
  auto reach = [](const Superellipsoid& s) { return std::sqrt(s.a * s.a + s.b * s.b + s.c * s.c); };
  while (scene.shapes.size() < 6) {  // fruits with at least 2 cm between their bounding spheres
    const Eigen::Vector3d c = plant + Eigen::Vector3d{0.2 * u(rng), 0.06 * u(rng), 0.2 * u(rng)};
    const Superellipsoid fruit = randomSuperellipsoid(rng, c);
    bool ok = true;
    for (const auto& s : scene.shapes) ok = ok && (s.t - c).norm() > reach(s) + reach(fruit) + 0.02;
    if (ok) scene.shapes.push_back(fruit);
  }
  const int n_fruits = static_cast<int>(scene.shapes.size());
  for (int i = 0; i < 10; ++i) {  // leaves: thin discs in front of and between the fruits
    Superellipsoid leaf;
    leaf.a = 0.05;
    leaf.b = 0.03;
    leaf.c = 0.002;
    leaf.e1 = 0.9;
    leaf.e2 = 1.0;
    leaf.t = plant + Eigen::Vector3d{0.18 * u(rng), -0.08 + 0.04 * u(rng), 0.18 * u(rng)};
    leaf.rpy = Eigen::Vector3d{M_PI / 2 + 0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng)};
    scene.shapes.push_back(leaf);
  }

  TsdfMap map;
  const TsdfIntegrator integrator;
  FruitShapePipeline pipeline;
  std::printf("fruit_shape_completion mapping demo: %d fruits behind 10 leaves, %d views, seed %u\n",
              n_fruits, views, seed);
  std::printf("(640x480 depth camera, 1 mm noise at 1 m; fruit pixels -> TSDF 4 mm -> surface -> "
              "clusters -> superellipsoids; accuracy over fruits found, Old = bounding box)\n\n");
  std::printf("%4s %8s %8s %6s %9s %9s %9s %9s %9s %9s\n", "view", "fruit_px", "surface", "fruits",
              "SE_acc", "Old_acc", "centre", "tsdf_ms", "surf_ms", "fit_ms");
  for (int v = 0; v < views; ++v) {
    // Camera on an arc in front of the plant, 0.45 m away, sweeping left to right and up.
    const double a = -1.1 + 2.2 * v / std::max(1, views - 1);
    const Eigen::Vector3d pos = plant + 0.45 * Eigen::Vector3d(std::sin(a), -std::cos(a), 0.25 * std::sin(2.0 * a));
    const PinholeCamera cam = PinholeCamera::lookingAt(pos, plant);
    const DepthScan scan = renderDepth(scene, cam, 0.001, seed * 1000 + v);
    PointList fruit;
    for (std::size_t k = 0; k < scan.points.size(); ++k)
      if (scan.labels[k] < n_fruits) fruit.push_back(scan.points[k]);
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = cam.rotation;
    pose.translation() = cam.position;
    const auto t0 = std::chrono::steady_clock::now();
    const IntegrationReport rep = integrator.integrate(map, fruit, pose);
    const auto t1 = std::chrono::steady_clock::now();
    const PointList surface = extractSurfacePoints(map);
    const auto t2 = std::chrono::steady_clock::now();
    const auto& fruits = pipeline.update(surface);
    const auto t3 = std::chrono::steady_clock::now();
    if (!rep.ok()) std::fprintf(stderr, "view %d: %s\n", v, rep.error.c_str());

    double acc = 0, old_acc = 0, err = 0;
    int found = 0;
    for (int f = 0; f < n_fruits; ++f) {
      const Superellipsoid& truth = scene.shapes[f];
      const FruitEstimate* best = nullptr;
      for (const auto& e : fruits)
        if (e.accepted && (!best || (e.center() - truth.t).norm() < (best->center() - truth.t).norm())) best = &e;
      if (!best || (best->center() - truth.t).norm() > 0.05) continue;
      ++found;
      acc += 1 - std::abs(best->volume - truth.volume()) / truth.volume();
      old_acc += 1 - std::abs(best->bbox_volume - truth.volume()) / truth.volume();
      err += (best->center() - truth.t).norm();
    }
    auto ms = [](auto d) { return std::chrono::duration<double, std::milli>(d).count(); };
    if (found > 0)
      std::printf("%4d %8zu %8zu %3d/%-2d %9.3f %9.3f %6.1f mm %9.1f %9.1f %9.1f\n", v + 1, fruit.size(),
                  surface.size(), found, n_fruits, acc / found, old_acc / found, 1000 * err / found,
                  ms(t1 - t0), ms(t2 - t1), ms(t3 - t2));
    else
      std::printf("%4d %8zu %8zu %3d/%-2d %9s %9s %9s %9.1f %9.1f %9.1f\n", v + 1, fruit.size(),
                  surface.size(), 0, n_fruits, "-", "-", "-", ms(t1 - t0), ms(t2 - t1), ms(t3 - t2));
  }
  std::printf("\nfinal fits:\n");
  for (const auto& f : pipeline.fruits())
    std::printf("  fruit %d: %d points, %.0f cm3%s%s\n", f.id, f.n_points, f.volume * 1e6,
                f.accepted ? "" : ", rejected: ", f.accepted ? "" : f.reason.c_str());
  std::printf("\nmap: %zu blocks, %zu observed voxels, %.1f MiB reserved\n", map.blockCount(),
              map.observedVoxelCount(), map.memoryBytes() / 1048576.0);
  if (!save_map.empty()) {
    std::string err;
    if (!map.save(save_map, &err)) {
      std::cerr << "demo_mapping: " << err << "\n";
      return 1;
    }
    std::printf("map saved to %s (inspect it with map_tool)\n", save_map.c_str());
  }
  return 0;
}
