// A greenhouse row: does the per-view work, and the map's memory, stay bounded as the map grows?
// A camera moves along one procedural row (procedural-row:1:100, about 390 fruits over 45 m) in
// the aisle, looking at the plants from two heights by turns, 0.12 m per view; the views are
// rendered once per process with the paper profile (textures, blurred depth noise) and replayed
// into a fresh estimator per iteration, every view timed as BM_PerViewUpdate times it
// (insertView, update, extraTargets). Three replays: a view's time is its median over them, so
// that a noisy moment on a shared machine does not pass for growth with the map (the early and
// the late set are 20 views each). Run: scripts/run.sh bench --benchmark_filter=RowScan
// --benchmark_format=json
#include <benchmark/benchmark.h>
#include <fruit_shape_completion/host/superellipsoid_estimator.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>

#include "../../src/instrument/planner/camera_step.h"
#include "bench_episode.h"

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

using namespace fruit_shape_completion;

namespace {

struct RowView {
  OrganizedFrame frame;
  Eigen::Isometry3d pose;
};

struct RowRecording {
  std::vector<RowView> views;
  int truth_fruits = 0;
  std::string error;
};

constexpr char kRowScene[] = "procedural-row:1:100";

const RowRecording& rowRecording() {
  static const RowRecording rec = [] {
    RowRecording r;
    sim::Scene scene;
    if (!sim::loadSceneSpec(kRowScene, &scene, &r.error)) return r;
    std::vector<int> triangle_fruit;
    r.truth_fruits = static_cast<int>(sim::computeFruitTruth(scene, &triangle_fruit).size());
    const planner::PlannerParams p = planner::paperProfile();
    sim::Shading shading;
    shading.textures = p.textures;
    const sim::RgbdRenderer renderer(scene, triangle_fruit, shading);
    sim::RedThreshold red_test;
    red_test.test = sim::RedThreshold::Test::kUpstream;
    const double first = scene.plants.front().position.x(), last = scene.plants.back().position.x();
    const double row_y = scene.plants.front().position.y();
    int k = 0;
    for (double x = first - 0.2; x <= last + 0.2; x += 0.12, ++k) {
      const double height = k % 2 == 0 ? 0.35 : 0.65;
      PinholeCamera cam;
      cam.position = Eigen::Vector3d(x, row_y - 0.45, height);
      cam.rotation = PinholeCamera::lookingAt(cam.position, Eigen::Vector3d(x + 0.05, row_y, height - 0.1)).rotation;
      const planner::CameraView v = planner::captureView(renderer, cam, p, red_test, k);
      r.views.push_back({v.organized, v.pose});
    }
    return r;
  }();
  return rec;
}

}  // namespace

static void BM_RowScan(benchmark::State& state) {
  const RowRecording& rec = rowRecording();
  if (!rec.error.empty() || rec.views.size() < 40) {
    state.SkipWithError(("no row to scan: " + rec.error).c_str());
    return;
  }
  const std::size_t n = rec.views.size();
  std::vector<std::vector<double>> view_ms(n);  // each view's time in every replay
  std::size_t fruits = 0;
  // integration, surface, clustering, rest of the pipeline, of which fits, everything else
  // (the input stage, targets, results); means over the first and the last 20 views of all replays.
  double early_parts[6] = {0, 0, 0, 0, 0, 0}, late_parts[6] = {0, 0, 0, 0, 0, 0};
  double map_mib = 0.0, save_ms = 0.0, load_ms = 0.0, file_mib = 0.0;
  const PointList none;
  for (auto _ : state) {
    host::SuperellipsoidEstimator estimator;
    for (std::size_t i = 0; i < n; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      host::ViewData view{none, none, rec.views[i].pose, 0.0, host::ViewSource::kCameraFrame};
      view.camera_frame = &rec.views[i].frame;
      estimator.insertView(view);
      estimator.update();
      const PointList extra = estimator.extraTargets();
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      view_ms[i].push_back(ms);
      if (i < 20 || i + 20 >= n) {
        double* parts = i < 20 ? early_parts : late_parts;
        const PipelineStats stats = estimator.lastPipelineStats();
        parts[0] += 1e3 * estimator.lastIntegration().seconds;
        parts[1] += 1e3 * estimator.lastSurfaceSeconds();
        parts[2] += 1e3 * stats.cluster_seconds;
        parts[3] += 1e3 * (stats.seconds - stats.cluster_seconds);
        parts[4] += 1e3 * stats.fit_seconds;
        parts[5] += ms - 1e3 * (estimator.lastIntegration().seconds + estimator.lastSurfaceSeconds() + stats.seconds);
      }
      benchmark::DoNotOptimize(extra.data());
    }
    fruits = 0;
    for (const auto& f : estimator.fruits()) fruits += f.accepted;
    map_mib = estimator.status().memory_mb;
    // The row's map saved and loaded back (atomic write, then a fresh estimator reads it).
    const std::string path = (std::filesystem::temp_directory_path() / "fsc_bench_row.tsdf").string();
    std::string error;
    const auto s0 = std::chrono::steady_clock::now();
    if (!estimator.saveMap(path, &error)) state.SkipWithError(("save: " + error).c_str());
    const auto s1 = std::chrono::steady_clock::now();
    host::SuperellipsoidEstimator reloaded;
    if (!reloaded.loadMap(path, &error)) state.SkipWithError(("load: " + error).c_str());
    const auto s2 = std::chrono::steady_clock::now();
    save_ms = std::chrono::duration<double, std::milli>(s1 - s0).count();
    load_ms = std::chrono::duration<double, std::milli>(s2 - s1).count();
    file_mib = static_cast<double>(std::filesystem::file_size(path)) / 1048576.0;
    std::filesystem::remove(path);
  }
  std::vector<double> early, late;  // the views' medians over the replays
  for (std::size_t i = 0; i < n; ++i) {
    if (i < 20) early.push_back(bench::quantile(view_ms[i], 0.5));
    if (i + 20 >= n) late.push_back(bench::quantile(view_ms[i], 0.5));
  }
  const double replays = static_cast<double>(view_ms.front().size());
  state.counters["views"] = static_cast<double>(n);
  state.counters["truth_fruits"] = rec.truth_fruits;
  state.counters["fruits"] = static_cast<double>(fruits);
  state.counters["early_median_ms"] = bench::quantile(early, 0.5);
  state.counters["early_p95_ms"] = bench::quantile(early, 0.95);
  state.counters["late_median_ms"] = bench::quantile(late, 0.5);
  state.counters["late_p95_ms"] = bench::quantile(late, 0.95);
  // Where the early and the late views' time goes (means over 20 views each).
  const char* part_names[] = {"integrate_ms", "surface_ms", "cluster_ms", "pipeline_rest_ms", "fit_ms", "other_ms"};
  for (int k = 0; k < 6; ++k) {
    state.counters[std::string("early_") + part_names[k]] = early_parts[k] / (replays * early.size());
    state.counters[std::string("late_") + part_names[k]] = late_parts[k] / (replays * late.size());
  }
  state.counters["map_MiB"] = map_mib;
  state.counters["MiB_per_fruit"] = fruits > 0 ? map_mib / static_cast<double>(fruits) : 0.0;
  state.counters["save_ms"] = save_ms;
  state.counters["load_ms"] = load_ms;
  state.counters["file_MiB"] = file_mib;
  state.SetLabel(kRowScene);
}
BENCHMARK(BM_RowScan)->Unit(benchmark::kMillisecond)->Iterations(3);
