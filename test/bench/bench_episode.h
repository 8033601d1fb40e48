#pragma once
// What the per-view benchmarks share: a seeded 120 s planner episode on scenario 2
// (../shared/data; the procedural glasshouse when it is absent), paper profile, whose views
// are handed to a callback, and quantiles of per-view times.
#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>

#include <algorithm>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace bench {

// Runs the episode; returns the scene it ran on. on_view gets what the estimators would get.
inline std::string recordEpisode(planner::PlannerParams::Input input,
                                 const std::function<void(const PinholeCamera&, const host::ViewData&)>& on_view) {
  const char* env = std::getenv("FSC_SHARED_DATA");
  std::string name = std::string(env ? env : "../shared/data") + "/scenes/scenario2_world19.yaml";
  sim::Scene scene;
  std::string err;
  if (!sim::loadSceneSpec(name, &scene, &err)) {
    name = "procedural";
    sim::loadSceneSpec(name, &scene, &err);
  }
  std::vector<int> triangle_fruit;
  const auto fruits = sim::computeFruitTruth(scene, &triangle_fruit);
  // The paper profile: textured plants, the paper's blurred depth noise, the arm; so the frames
  // look like what a robot's camera delivers and pointcloud_roi's red test picks the fruit.
  planner::PlannerParams params = planner::paperProfile();
  params.duration = 120.0;
  params.seed = 3;
  params.charge_compute_time = false;  // the same views on every run, whatever the machine's load
  params.input = input;
  const planner::SceneTruth truth = planner::makeSceneTruth(fruits, params.octree_resolution);
  sim::Shading shading;
  shading.textures = params.textures;
  const sim::RgbdRenderer renderer(scene, triangle_fruit, shading);
  host::ShapeEstimatorHost host;  // none: the episode only records what the camera saw
  planner::runEpisode(scene, renderer, truth, host, params,
                      [&](const planner::ViewRecord&, const planner::RoiOcTree&, const sim::RgbdFrame& frame,
                          const host::ViewData& view) {
                        on_view(frame.camera, view);
                        return true;
                      });
  return name;
}

inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

}  // namespace bench
}  // namespace fruit_shape_completion
