// The whole per-view update as the plugin runs it: the camera's organized frame through the
// fruit input stage (red test, depth edges, outliers) into the TSDF map, extract the surface, cluster, fit incrementally, predict the missing surface, hand out
// the extra targets. Run: scripts/run.sh bench --benchmark_filter=PerView --benchmark_format=json
//
// The view sequences are recorded once per process from seeded planner episodes on scenario 2
// (../shared/data; the procedural glasshouse when it is absent): the organized frame and the
// sensor pose of every view, with depth noise. Each iteration replays each episode into a fresh
// estimator.
#include <benchmark/benchmark.h>
#include <fruit_shape_completion/host/superellipsoid_estimator.h>
#include <fruit_shape_completion/host/shape_estimator.h>

#include "bench_episode.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

using namespace fruit_shape_completion;

namespace {

struct RecordedView {
  OrganizedFrame frame;  // the camera's organized cloud, as a real camera publishes it
  Eigen::Isometry3d pose;
};

struct Recording {
  std::string scene;
  std::vector<std::vector<RecordedView>> episodes;
};

const Recording& recording() {
  static const Recording rec = [] {
    Recording r;
    for (unsigned seed : bench::kEpisodeSeeds) {
      r.episodes.emplace_back();
      auto& views = r.episodes.back();
      r.scene = bench::recordEpisode(planner::PlannerParams::Input::kCamera, seed,
                                     [&](const PinholeCamera&, const host::ViewData& view) {
                                       views.push_back({*view.camera_frame, view.sensor_pose});
                                     });
    }
    return r;
  }();
  return rec;
}

}  // namespace

static void BM_PerViewUpdate(benchmark::State& state) {
  const Recording& rec = recording();
  if (rec.episodes.empty() || rec.episodes.front().empty()) {
    state.SkipWithError("the recorded episode has no views");
    return;
  }
  std::vector<double> per_view_ms;
  double integrate_s = 0, merge_s = 0, neighbourhood_s = 0, rays_s = 0, surface_s = 0, cluster_s = 0, fit_s = 0,
         pipeline_s = 0, prior_s = 0, missing_s = 0;
  std::size_t fruits = 0, targets = 0, fits = 0, kept = 0, points = 0;
  const PointList none;
  // FSC_PER_VIEW_CSV=path: one line per view (its wall time and its parts, CPU of the fits summed
  // over their threads), to see what makes the slowest views.
  FILE* view_log = std::getenv("FSC_PER_VIEW_CSV") ? std::fopen(std::getenv("FSC_PER_VIEW_CSV"), "w") : nullptr;
  if (view_log)
    std::fprintf(view_log, "view,ms,integrate_ms,surface_ms,cluster_ms,pipeline_ms,prior_ms,fit_cpu_ms,missing_ms,clusters,fits,kept,fruits\n");
  for (auto _ : state) {
    fruits = 0;
    for (const auto& episode : rec.episodes) {
      host::SuperellipsoidEstimator estimator;
      for (const auto& v : episode) {
        const auto t0 = std::chrono::steady_clock::now();
        host::ViewData view{none, none, v.pose, 0.0, host::ViewSource::kCameraFrame};
        view.camera_frame = &v.frame;
        estimator.insertView(view);
        estimator.update();  // integrates the view, then fits
        const IntegrationReport integration = estimator.lastIntegration();
        integrate_s += integration.seconds;
        merge_s += integration.merge_seconds;
        neighbourhood_s += integration.neighbourhood_seconds;
        rays_s += integration.ray_seconds;
        points += integration.points_in;
        const PipelineStats stats = estimator.lastPipelineStats();
        surface_s += estimator.lastSurfaceSeconds();
        cluster_s += stats.cluster_seconds;
        fit_s += stats.fit_seconds;
        pipeline_s += stats.seconds;
        prior_s += stats.prior_seconds;
        missing_s += stats.missing_seconds;
        fits += static_cast<std::size_t>(stats.fitted);
        kept += static_cast<std::size_t>(stats.kept);
        const PointList extra = estimator.extraTargets();
        const auto t1 = std::chrono::steady_clock::now();
        per_view_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
        if (view_log)
          std::fprintf(view_log, "%zu,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%d,%d,%zu\n", per_view_ms.size() - 1,
                       per_view_ms.back(), 1e3 * integration.seconds, 1e3 * estimator.lastSurfaceSeconds(),
                       1e3 * stats.cluster_seconds, 1e3 * stats.seconds, 1e3 * stats.prior_seconds,
                       1e3 * stats.fit_seconds, 1e3 * stats.missing_seconds, stats.clusters, stats.fitted, stats.kept,
                       estimator.sharedFruits()->size());
        targets = extra.size();
      }
      fruits += estimator.fruits().size();
    }
  }
  if (view_log) std::fclose(view_log);
  state.counters["episodes"] = static_cast<double>(rec.episodes.size());
  state.counters["views"] = static_cast<double>(per_view_ms.size() / state.iterations());
  state.counters["median_ms"] = bench::quantile(per_view_ms, 0.5);
  state.counters["p95_ms"] = bench::quantile(per_view_ms, 0.95);
  state.counters["max_ms"] = *std::max_element(per_view_ms.begin(), per_view_ms.end());
  // Of which the TSDF integration, and its outlier filter and normals (mean per view).
  state.counters["integrate_ms"] = 1e3 * integrate_s / static_cast<double>(per_view_ms.size());
  state.counters["merge_ms"] = 1e3 * merge_s / static_cast<double>(per_view_ms.size());
  state.counters["neighbourhood_ms"] = 1e3 * neighbourhood_s / static_cast<double>(per_view_ms.size());
  state.counters["rays_ms"] = 1e3 * rays_s / static_cast<double>(per_view_ms.size());
  state.counters["points"] = static_cast<double>(points) / static_cast<double>(per_view_ms.size());
  // The rest of the update (mean per view), and the fits run per episode: a change of workload
  // (more refits) shows here, not as a slower fit.
  state.counters["surface_ms"] = 1e3 * surface_s / static_cast<double>(per_view_ms.size());
  state.counters["cluster_ms"] = 1e3 * cluster_s / static_cast<double>(per_view_ms.size());
  state.counters["pipeline_ms"] = 1e3 * pipeline_s / static_cast<double>(per_view_ms.size());
  state.counters["prior_ms"] = 1e3 * prior_s / static_cast<double>(per_view_ms.size());
  state.counters["fit_ms"] = 1e3 * fit_s / static_cast<double>(per_view_ms.size());
  state.counters["missing_ms"] = 1e3 * missing_s / static_cast<double>(per_view_ms.size());
  state.counters["fits"] = static_cast<double>(fits) / static_cast<double>(state.iterations());
  // Changed clusters the previous fit still explained: not refitted.
  state.counters["kept"] = static_cast<double>(kept) / static_cast<double>(state.iterations());
  state.counters["fruits"] = static_cast<double>(fruits);
  state.counters["targets"] = static_cast<double>(targets);
  state.SetLabel(rec.scene);
}
BENCHMARK(BM_PerViewUpdate)->Unit(benchmark::kMillisecond)->Iterations(3);

// What the planner blocks on with the plugin's host: onView of an organized 640x480 camera frame
// (the input stage; the worker integrates the fruit points before it fits), each view meeting
// the running update of the one before (bench::Pace). Counters over all views.
static void insertCameraFrames(benchmark::State& state, bench::Pace pace) {
  const Recording& rec = recording();
  const PointList none;
  bench::insertViewLatency(state, bench::episodeSizes(rec.episodes), pace, [&](host::ShapeEstimatorHost& host, std::size_t e, std::size_t k) {
    const RecordedView& v = rec.episodes[e][k];
    host::ViewData view{none, none, v.pose, 0.0, host::ViewSource::kCameraFrame};
    view.camera_frame = &v.frame;
    host.onView(view);
    return std::string();
  });
  state.SetLabel(rec.scene);
}
static void BM_InsertViewLatencyCameraFrame(benchmark::State& state) { insertCameraFrames(state, bench::Pace::kMeetsUpdate); }
BENCHMARK(BM_InsertViewLatencyCameraFrame)->Name("BM_InsertViewLatency/camera_frame_640x480")
    ->Unit(benchmark::kMillisecond)->Iterations(3);
// The same views back to back, faster than the worker takes them (bench::Pace::kBackToBack).
static void BM_InsertViewLatencyCameraFrameBackToBack(benchmark::State& state) {
  insertCameraFrames(state, bench::Pace::kBackToBack);
}
BENCHMARK(BM_InsertViewLatencyCameraFrameBackToBack)->Name("BM_InsertViewLatency/camera_frame_640x480_back_to_back")
    ->Unit(benchmark::kMillisecond)->Iterations(3);
