// TSDF map and point-cloud benchmarks. Run: scripts/run.sh bench --benchmark_filter='Tsdf|FiftyFruit' --benchmark_format=json
#include <benchmark/benchmark.h>
#include <fruit_shape_completion/instrument/sim/analytic_depth_camera.h>
#include <fruit_shape_completion/euclidean_clustering.h>
#include <fruit_shape_completion/missing_surface.h>
#include <fruit_shape_completion/statistical_outlier_filter.h>
#include <fruit_shape_completion/surface_normals.h>
#include <fruit_shape_completion/tsdf_integrator.h>
#include <fruit_shape_completion/tsdf_surface.h>

#include <cmath>
#include <memory>
#include <random>

using namespace fruit_shape_completion;

namespace {

// A cluster of fruit-sized superellipsoids around `center`.
AnalyticScene fruitCluster(const Eigen::Vector3d& center, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1), r(0.03, 0.045), e(0.5, 0.9);
  AnalyticScene scene;
  while (static_cast<int>(scene.shapes.size()) < n) {
    Superellipsoid s;
    s.a = r(rng); s.b = r(rng); s.c = r(rng); s.e1 = e(rng); s.e2 = e(rng);
    s.rpy = Eigen::Vector3d{u(rng), u(rng), u(rng)};
    s.t = center + Eigen::Vector3d{0.12 * u(rng), 0.12 * u(rng), 0.12 * u(rng)};
    bool overlaps = false;
    for (const auto& o : scene.shapes) overlaps = overlaps || (o.t - s.t).norm() < 0.11;
    if (!overlaps) scene.shapes.push_back(s);
  }
  return scene;
}

PointList view(const AnalyticScene& scene, const Eigen::Vector3d& target, const Eigen::Vector3d& dir,
               double dist, Eigen::Vector3d* origin) {
  const PinholeCamera cam = PinholeCamera::lookingAt(target + dist * dir.normalized(), target);
  *origin = cam.position;
  return renderDepth(scene, cam, 0.0015).points;  // ~0.25 mm noise at 0.4 m
}

// A full 640 x 480 frame: two fruit clusters and a back wall, 0.3-1.5 m.
PointList fullFrame(PinholeCamera* cam) {
  AnalyticScene scene = fruitCluster(Eigen::Vector3d(0.0, 0.5, 0.5), 6, 3);
  const AnalyticScene far = fruitCluster(Eigen::Vector3d(0.1, 1.0, 0.5), 6, 4);
  scene.shapes.insert(scene.shapes.end(), far.shapes.begin(), far.shapes.end());
  scene.planes.push_back({Eigen::Vector3d(0, 1.5, 0), Eigen::Vector3d(0, -1, 0)});
  *cam = PinholeCamera::lookingAt(Eigen::Vector3d(0, 0, 0.5), Eigen::Vector3d(0, 1, 0.5));
  return renderDepth(scene, *cam, 0.0015).points;
}

}  // namespace

// One masked fruit frame (only fruit pixels, 640 x 480, fruits at 0.3-0.5 m) into a map that
// already holds 20 views of the same fruits.
static void BM_TsdfIntegrateFruitFrame(benchmark::State& state) {
  const Eigen::Vector3d center(0.0, 0.6, 0.5);
  const AnalyticScene scene = fruitCluster(center, 6, 7);
  TsdfMap map;
  const TsdfIntegrator integ;
  const PointList dirs = fibonacciSphere(21);
  Eigen::Vector3d origin;
  for (int i = 0; i < 20; ++i) integ.integrate(map, view(scene, center, dirs[i], 0.4, &origin), origin);
  const PointList frame = view(scene, center, dirs[20], 0.4, &origin);
  IntegrationReport r;
  for (auto _ : state) r = integ.integrate(map, frame, origin);
  state.counters["points"] = static_cast<double>(frame.size());
  state.counters["rays"] = static_cast<double>(r.rays);
  state.counters["merge_ms"] = 1e3 * r.merge_seconds;
  state.counters["neighbourhood_ms"] = 1e3 * r.neighbourhood_seconds;
  state.counters["rays_ms"] = 1e3 * r.ray_seconds;
  state.counters["blocks"] = static_cast<double>(map.blockCount());
}
BENCHMARK(BM_TsdfIntegrateFruitFrame)->Unit(benchmark::kMillisecond);

// A full 640 x 480 frame (two fruit clusters and a back wall; 0.3-1.5 m) at 4 mm.
// Arg 1: default integrator (outlier removal and incidence-limited band, which need a
// neighbourhood pass over all merged points); Arg 0: both off. Second arg: 0 into a fresh map
// (allocating its blocks is included), 1 into a map that already holds this area (as every
// later frame of a run).
static void BM_TsdfIntegrateFullFrame(benchmark::State& state) {
  PinholeCamera cam;
  const PointList frame = fullFrame(&cam);
  TsdfIntegratorParams params;
  params.remove_outliers = params.incidence_limited_back_band = state.range(0) != 0;
  const TsdfIntegrator integ(params);
  std::size_t rays = 0, blocks = 0;
  double merge = 0, neighbourhood = 0, cast = 0;  // phase seconds summed over the iterations
  auto phases = [&](const IntegrationReport& r) {
    merge += r.merge_seconds;
    neighbourhood += r.neighbourhood_seconds;
    cast += r.ray_seconds;
    return r.rays;
  };
  const bool warm = state.range(1) != 0;
  TsdfMap warm_map;
  if (warm) integ.integrate(warm_map, frame, cam.position);
  for (auto _ : state) {
    if (warm) {
      rays = phases(integ.integrate(warm_map, frame, cam.position));
    } else {
      state.PauseTiming();
      auto map = std::make_unique<TsdfMap>();
      state.ResumeTiming();
      rays = phases(integ.integrate(*map, frame, cam.position));
      state.PauseTiming();
      blocks = map->blockCount();
      map.reset();  // freeing the blocks is not part of the integration
      state.ResumeTiming();
    }
  }
  state.counters["points"] = static_cast<double>(frame.size());
  state.counters["rays"] = static_cast<double>(rays);
  state.counters["blocks"] = static_cast<double>(warm ? warm_map.blockCount() : blocks);
  // Mean milliseconds per frame of each phase (IntegrationReport's timings).
  const double per_ms = 1e3 / static_cast<double>(state.iterations());
  state.counters["merge_ms"] = merge * per_ms;
  state.counters["neighbourhood_ms"] = neighbourhood * per_ms;
  state.counters["rays_ms"] = cast * per_ms;
}
BENCHMARK(BM_TsdfIntegrateFullFrame)
    ->Args({1, 0})->Args({1, 1})->Args({0, 0})->Args({0, 1})
    ->Unit(benchmark::kMillisecond);


// A map holding 50 fruits, each cluster of 5 seen from 6 directions, along a 3 m row.
const TsdfMap& fiftyFruitMap() {
  static const TsdfMap map = [] {
    TsdfMap m;
    const TsdfIntegrator integ;
    const PointList dirs = fibonacciSphere(6);
    for (int c = 0; c < 10; ++c) {
      const Eigen::Vector3d center(0.3 * c, 0.6, 0.5);
      const AnalyticScene scene = fruitCluster(center, 5, 100 + c);
      for (const auto& d : dirs) {
        const PinholeCamera cam = PinholeCamera::lookingAt(center + 0.4 * d, center, 320, 240);
        integ.integrate(m, renderDepth(scene, cam).points, cam.position);
      }
    }
    return m;
  }();
  return map;
}

// Surface extraction from the 50-fruit map.
static void BM_TsdfExtractSurface(benchmark::State& state) {
  const TsdfMap& map = fiftyFruitMap();
  std::size_t n = 0;
  SurfaceExtractionParams extraction;
  extraction.project_to_zero_crossing = state.range(0) != 0;
  for (auto _ : state) {
    const PointList surface = extractSurfacePoints(map, extraction);
    n = surface.size();
    benchmark::DoNotOptimize(surface.data());
  }
  state.counters["surface_points"] = static_cast<double>(n);
  state.counters["blocks"] = static_cast<double>(map.blockCount());
  state.counters["observed_voxels"] = static_cast<double>(map.observedVoxelCount());
  state.counters["map_MiB"] = map.memoryBytes() / 1048576.0;
}
// Arg 0: voxel centres (as voxblox), 1: projected onto the zero crossing.
BENCHMARK(BM_TsdfExtractSurface)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The point-cloud steps of an update on the 50-fruit map's surface (PCL underneath).
static void BM_FiftyFruitClustering(benchmark::State& state) {
  const PointList surface = extractSurfacePoints(fiftyFruitMap());
  std::size_t clusters = 0;
  for (auto _ : state) clusters = euclideanClusters(surface, ClusteringParams()).size();
  state.counters["points"] = static_cast<double>(surface.size());
  state.counters["clusters"] = static_cast<double>(clusters);
}
BENCHMARK(BM_FiftyFruitClustering)->Unit(benchmark::kMillisecond);

static void BM_FiftyFruitOutliers(benchmark::State& state) {
  const PointList surface = extractSurfacePoints(fiftyFruitMap());
  for (auto _ : state) benchmark::DoNotOptimize(findStatisticalOutliers(surface, OutlierFilterParams()).data());
  state.counters["points"] = static_cast<double>(surface.size());
}
BENCHMARK(BM_FiftyFruitOutliers)->Unit(benchmark::kMillisecond);

// All normals (max_points 0) of the surface, 1.5 cm neighbourhoods.
static void BM_FiftyFruitNormals(benchmark::State& state) {
  const PointList surface = extractSurfacePoints(fiftyFruitMap());
  NormalParams params;
  params.max_points = 0;
  for (auto _ : state) benchmark::DoNotOptimize(estimateNormals(surface, params, Eigen::Vector3d::Zero()).valid);
  state.counters["points"] = static_cast<double>(surface.size());
}
BENCHMARK(BM_FiftyFruitNormals)->Unit(benchmark::kMillisecond);

// The fruits of the 50-fruit map, each half seen (its points on one side of its centroid), and
// a sphere of its size at its centroid (the shape the missing-surface test samples).
const std::vector<std::pair<PointList, Superellipsoid>>& fiftyFruitShapes() {
  static const auto shapes = [] {
    std::vector<std::pair<PointList, Superellipsoid>> out;
    const PointList surface = extractSurfacePoints(fiftyFruitMap());
    for (const auto& cluster : euclideanClusters(surface, ClusteringParams())) {
      PointList pts;
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (int i : cluster) {
        pts.push_back(surface[static_cast<std::size_t>(i)]);
        mean += pts.back();
      }
      mean /= static_cast<double>(pts.size());
      double r = 0.0;
      PointList half;
      for (const auto& p : pts) {
        r += (p - mean).norm();
        if (p.x() > mean.x()) half.push_back(p);
      }
      out.emplace_back(half, Superellipsoid::sphere(r / static_cast<double>(pts.size()), mean));
    }
    return out;
  }();
  return shapes;
}

// The missing surface of every fruit, its index built afresh as after a refit.
static void BM_FiftyFruitMissingSurface(benchmark::State& state) {
  const auto& shapes = fiftyFruitShapes();
  std::size_t missing = 0;
  for (auto _ : state) {
    missing = 0;
    for (const auto& s : shapes) missing += predictMissingSurface(s.second, s.first, MissingSurfaceParams()).size();
  }
  state.counters["fruits"] = static_cast<double>(shapes.size());
  state.counters["missing"] = static_cast<double>(missing);
}
BENCHMARK(BM_FiftyFruitMissingSurface)->Unit(benchmark::kMillisecond);

// Clustering on hostile input: Arg 0: 100 k identical points; Arg 1: 1 M points uniformly random
// in a 1 m cube (1 cm tolerance, as the pipeline).
static void BM_ClusteringHostile(benchmark::State& state) {
  PointList points;
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  if (state.range(0) == 0) points.assign(100000, Eigen::Vector3d(0.3, 0.2, 0.1));
  else
    for (int i = 0; i < 1000000; ++i) points.push_back(Eigen::Vector3d{u(rng), u(rng), u(rng)});
  ClusteringParams params;
  params.min_size = 1;
  params.max_size = 2000000;
  std::size_t clusters = 0;
  for (auto _ : state) clusters = euclideanClusters(points, params).size();
  state.counters["points"] = static_cast<double>(points.size());
  state.counters["clusters"] = static_cast<double>(clusters);
}
BENCHMARK(BM_ClusteringHostile)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
