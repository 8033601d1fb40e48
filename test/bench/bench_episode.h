#pragma once
// What the per-view benchmarks share: seeded 120 s planner episodes on scenario 2
// (../shared/data; the procedural glasshouse when it is absent), paper profile, whose views
// are handed to a callback, and quantiles of per-view times. Several episodes, because how
// much a view costs depends most on how many new fruits it reveals, which one episode's 25
// views sample poorly.
#include <benchmark/benchmark.h>
#include <fruit_shape_completion/host/superellipsoid_estimator.h>
#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace fruit_shape_completion {
namespace bench {

constexpr unsigned kEpisodeSeeds[] = {3, 4, 5};

// Runs the episode; returns the scene it ran on. on_view gets what the estimators would get;
// on_tree, if given, the planner's octree after each view.
inline std::string recordEpisode(planner::PlannerParams::Input input, unsigned seed,
                                 const std::function<void(const PinholeCamera&, const host::ViewData&)>& on_view,
                                 const std::function<void(const planner::RoiOcTree&)>& on_tree = nullptr) {
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
  params.seed = seed;
  params.charge_compute_time = false;  // the same views on every run, whatever the machine's load
  params.input = input;
  const planner::SceneTruth truth = planner::makeSceneTruth(fruits, params.octree_resolution);
  sim::Shading shading;
  shading.textures = params.textures;
  const sim::RgbdRenderer renderer(scene, triangle_fruit, shading);
  host::ShapeEstimatorHost host;  // none: the episode only records what the camera saw
  planner::runEpisode(scene, renderer, truth, host, params,
                      [&](const planner::ViewRecord&, const planner::RoiOcTree& tree, const sim::RgbdFrame& frame,
                          const host::ViewData& view) {
                        on_view(frame.camera, view);
                        if (on_tree) on_tree(tree);
                        return true;
                      });
  return name;
}

// The number of views of each recorded episode.
template <typename View>
std::vector<std::size_t> episodeSizes(const std::vector<std::vector<View>>& episodes) {
  std::vector<std::size_t> sizes;
  for (const auto& e : episodes) sizes.push_back(e.size());
  return sizes;
}

inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

// How views follow one another in insertViewLatency.
enum class Pace {
  // The next view as soon as the worker has started the update of the one before: every view
  // meets a running update (integration and fits on the other threads), as fast as the
  // estimator takes views. A planner between two views samples, plans and moves for far longer.
  kMeetsUpdate,
  // Back to back, faster than any update can take them: the queue of waiting views fills up
  // and each call integrates the oldest itself. The saturated worst case.
  kBackToBack,
};

// What a planner blocks on: per episode e, views[e] calls of insert(host, e, k), each timed, into
// a fresh host in background mode with the superellipsoid estimator (the updates run on its
// worker), paced as `pace` says. insert returns "" or why it cannot go on.
// Counters: median_ms, p95_ms, max_ms over all calls; fits run and fruits at the end, summed
// over the episodes; max_waiting, the most views seen waiting for the map after a call.
template <typename Insert>
void insertViewLatency(benchmark::State& state, const std::vector<std::size_t>& views, Pace pace, Insert&& insert) {
  std::size_t total = 0;
  for (std::size_t n : views) total += n;
  if (total == 0) {
    state.SkipWithError("the recorded episodes have no views");
    return;
  }
  std::vector<double> blocked_ms;
  std::size_t fits = 0, fruits = 0, max_waiting = 0;
  for (auto _ : state) {
    fruits = 0;
    for (std::size_t e = 0; e < views.size(); ++e) {
      host::ShapeEstimatorHost host(nullptr, host::ShapeEstimatorHost::Updates::kBackground);
      host.add(std::make_unique<host::SuperellipsoidEstimator>());
      const auto& estimator = dynamic_cast<const host::SuperellipsoidEstimator&>(host.estimator(0));
      for (std::size_t k = 0; k < views[e]; ++k) {
        const auto t0 = std::chrono::steady_clock::now();
        const std::string error = insert(host, e, k);
        if (!error.empty()) {
          state.SkipWithError(error.c_str());
          return;
        }
        blocked_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        max_waiting = std::max(max_waiting, estimator.pendingViews());
        if (pace == Pace::kMeetsUpdate) {
          const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
          while (host.updateStatus(0).pending) {
            if (std::chrono::steady_clock::now() > deadline) {
              state.SkipWithError("the worker took no update for 60 s");
              return;
            }
            std::this_thread::sleep_for(std::chrono::microseconds(100));
          }
        }
      }
      host.waitForUpdates(60.0);
      fits += host.updateStatus(0).runs;
      fruits += host.fruits(0).size();
    }
  }
  state.counters["episodes"] = static_cast<double>(views.size());
  state.counters["views"] = static_cast<double>(total);
  state.counters["median_ms"] = quantile(blocked_ms, 0.5);
  state.counters["p95_ms"] = quantile(blocked_ms, 0.95);
  state.counters["max_ms"] = *std::max_element(blocked_ms.begin(), blocked_ms.end());
  state.counters["fits"] = static_cast<double>(fits) / static_cast<double>(state.iterations());
  state.counters["fruits"] = static_cast<double>(fruits);
  state.counters["max_waiting"] = static_cast<double>(max_waiting);
}

}  // namespace bench
}  // namespace fruit_shape_completion
