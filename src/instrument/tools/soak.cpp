// Soak test of the estimator as the planner hosts it: many views into one estimator, never
// reset, sampling the process's resident memory. The views are recorded once from seeded
// planner episodes on a scene and replayed in a loop, each replay with fresh depth noise (1 mm),
// so the map keeps changing as under a camera that keeps looking.
//   soak [--scene FILE|procedural[:SEED]] [--views N] [--episodes E] [--sample-every K] [--out F.csv]
#include <fruit_shape_completion/host/superellipsoid_estimator.h>
#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include "command_line.h"

#include <iostream>
#include <random>

using namespace fruit_shape_completion;

namespace {

double residentMb() {
  std::ifstream statm("/proc/self/statm");
  long pages = 0, resident = 0;
  statm >> pages >> resident;
  return static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

struct RecordedView {
  PointList fruit;
  Eigen::Isometry3d pose;
};

}  // namespace

int main(int argc, char** argv) {
  std::string spec, out = "soak.csv";
  long views = 10000, sample_every = 100;
  int episodes = 4;
  CLI::App app("Soak test of the estimator as the planner hosts it: many views into one estimator, never reset,\n"
               "sampling the process's resident memory.", "soak");
  app.add_option("--scene", spec, "scene file, or procedural[:SEED] (default: scenario 2 in ../shared/data)");
  app.add_option("--views", views, "views in all")->check(CLI::Range(1L, 100000000L))->capture_default_str();
  app.add_option("--episodes", episodes, "episodes recorded and replayed")->check(CLI::Range(1, 1000))->capture_default_str();
  app.add_option("--sample-every", sample_every, "views between memory samples")->check(CLI::Range(1L, 100000000L))
      ->capture_default_str();
  app.add_option("--out", out, "CSV of the samples")->capture_default_str();
  if (const int done = parseCommandLine(app, argc, argv); done >= 0) return done;
  if (spec.empty()) {
    const char* env = std::getenv("FSC_SHARED_DATA");
    spec = std::string(env ? env : "../shared/data") + "/scenes/scenario2_world19.yaml";
  }
  sim::Scene scene;
  std::string err;
  if (!sim::loadSceneSpec(spec, &scene, &err)) {
    std::cerr << "soak: " << err << "\n";
    return 1;
  }
  std::vector<int> triangle_fruit;
  const auto truth_fruits = sim::computeFruitTruth(scene, &triangle_fruit);
  const sim::RgbdRenderer renderer(scene, triangle_fruit);
  std::vector<RecordedView> recorded;
  const FruitInputStage stage;
  for (int e = 0; e < episodes; ++e) {
    planner::PlannerParams params;
    params.seed = 11 + static_cast<unsigned>(e);
    const planner::SceneTruth truth = planner::makeSceneTruth(truth_fruits, params.octree_resolution);
    host::ShapeEstimatorHost none;
    planner::runEpisode(scene, renderer, truth, none, params,
                        [&](const planner::ViewRecord&, const planner::RoiOcTree&, const sim::RgbdFrame&,
                            const host::ViewData& view) {
                          // The stage's output: the soak replays fruit points, not whole frames.
                          const FruitInput in = stage.processFrame(*view.camera_frame, view.sensor_pose, view.fruit_mask);
                          recorded.push_back({in.fruit, view.sensor_pose});
                          return true;
                        });
  }
  if (recorded.empty()) {
    std::cerr << "soak: the episodes recorded no views\n";
    return 1;
  }
  std::cerr << "soak: " << recorded.size() << " recorded views of " << scene.name << "; replaying " << views
            << " into one estimator\n";

  host::ShapeEstimatorHost host;
  auto estimator = std::make_unique<host::SuperellipsoidEstimator>();
  const host::SuperellipsoidEstimator& se = *estimator;
  host.add(std::move(estimator));
  std::ofstream csv(out);
  csv << "view,rss_mb,map_mb,blocks,fruits,view_ms\n";
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.001);
  const PointList no_full;
  const double rss_start = residentMb();
  double rss_max = rss_start, rss_at_tenth = 0.0, slowest_ms = 0.0;
  PointList noisy;
  for (long v = 0; v < views; ++v) {
    const RecordedView& rv = recorded[static_cast<std::size_t>(v) % recorded.size()];
    noisy = rv.fruit;
    for (auto& p : noisy) p += Eigen::Vector3d{noise(rng), noise(rng), noise(rng)};
    const auto t0 = std::chrono::steady_clock::now();
    host.onView(host::ViewData{noisy, no_full, rv.pose, static_cast<double>(v)});
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    slowest_ms = std::max(slowest_ms, ms);
    if ((v + 1) % sample_every == 0 || v + 1 == views) {
      const double rss = residentMb();
      rss_max = std::max(rss_max, rss);
      if (rss_at_tenth == 0.0 && v + 1 >= views / 10) rss_at_tenth = rss;
      const host::EstimatorStatus st = se.status();
      csv << v + 1 << "," << rss << "," << st.memory_mb << "," << st.blocks << "," << st.fruits << "," << ms << "\n";
      std::fprintf(stderr, "soak: view %ld: RSS %.1f MB, map %.1f MB in %zu blocks, %zu fruits\n", v + 1, rss,
                   st.memory_mb, st.blocks, st.fruits);
    }
  }
  const double rss_end = residentMb();
  std::printf("soak: %ld views: RSS %.1f MB at the start, %.1f MB after a tenth, %.1f MB at the end (max %.1f); "
              "slowest view %.0f ms; estimator %s; per-sample figures in %s\n",
              views, rss_start, rss_at_tenth, rss_end, rss_max, slowest_ms,
              host.enabled(0) ? "enabled" : ("disabled: " + host.lastError(0)).c_str(), out.c_str());
  return host.enabled(0) ? 0 : 1;
}
