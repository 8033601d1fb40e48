// TSDF map benchmarks. Run: scripts/run.sh bench --benchmark_filter='Tsdf|Neighbourhood' --benchmark_format=json
#include <benchmark/benchmark.h>
#include <fruit_shape_completion/analytic_depth_camera.h>
#include <fruit_shape_completion/neighbourhood_statistics.h>
#include <fruit_shape_completion/spatial_hash_grid.h>
#include <fruit_shape_completion/tsdf_integrator.h>
#include <fruit_shape_completion/tsdf_surface.h>

#include <cmath>
#include <memory>
#include <random>
#include <unordered_map>

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
    s.rpy = Eigen::Vector3d(u(rng), u(rng), u(rng));
    s.t = center + Eigen::Vector3d(0.12 * u(rng), 0.12 * u(rng), 0.12 * u(rng));
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
  for (auto _ : state) benchmark::DoNotOptimize(integ.integrate(map, frame, origin).rays);
  state.counters["points"] = static_cast<double>(frame.size());
  state.counters["blocks"] = static_cast<double>(map.blockCount());
}
BENCHMARK(BM_TsdfIntegrateFruitFrame)->Unit(benchmark::kMillisecond);

// A full 640 x 480 frame (two fruit clusters and a back wall; 0.3-1.5 m) at 4 mm.
// Arg 1: default integrator (outlier removal and incidence-limited band, which need a
// neighbourhood pass over all merged points); Arg 0: both off. Second arg: threads. Third
// arg: 0 into a fresh map (first touch of every block page is included), 1 into a map that
// already holds this area (as every later frame of a run).
static void BM_TsdfIntegrateFullFrame(benchmark::State& state) {
  PinholeCamera cam;
  const PointList frame = fullFrame(&cam);
  TsdfIntegratorParams params;
  params.remove_outliers = params.incidence_limited_back_band = state.range(0) != 0;
  params.threads = static_cast<int>(state.range(1));
  const TsdfIntegrator integ(params);
  std::size_t rays = 0, blocks = 0;
  double merge = 0, neighbourhood = 0, cast = 0;  // phase seconds summed over the iterations
  auto phases = [&](const IntegrationReport& r) {
    merge += r.merge_seconds;
    neighbourhood += r.neighbourhood_seconds;
    cast += r.ray_seconds;
    return r.rays;
  };
  const bool warm = state.range(2) != 0;
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
    ->Args({1, 1, 0})->Args({1, 1, 1})->Args({1, 2, 0})->Args({1, 2, 1})
    ->Args({0, 1, 0})->Args({0, 1, 1})->Args({0, 2, 0})->Args({0, 2, 1})
    ->Unit(benchmark::kMillisecond);

// The integrator's neighbourhood pass alone (neighbourhood_statistics.h), on the full frame's
// points merged per 4 mm voxel (283 k), at the defaults (1 cm, k 10), one thread, its grid
// kept between calls as the integrator keeps it. Arg: 0 k-NN means and normals, 1 normals
// only, 2 k-NN means only, 3 building the grid only.
static void BM_NeighbourhoodPass(benchmark::State& state) {
  PinholeCamera cam;
  const PointList frame = fullFrame(&cam);
  std::unordered_map<std::uint64_t, std::size_t> slot;
  PointList sums;
  std::vector<int> counts;
  for (const Point& p : frame) {
    const Eigen::Vector3d v = (p / 0.004).array().floor();
    const auto ins = slot.emplace(SpatialHashGrid::packKey(static_cast<std::int64_t>(v.x()), static_cast<std::int64_t>(v.y()),
                                                           static_cast<std::int64_t>(v.z())),
                                  sums.size());
    if (ins.second) {
      sums.push_back(Point::Zero());
      counts.push_back(0);
    }
    sums[ins.first->second] += p;
    ++counts[ins.first->second];
  }
  PointList ends(sums.size());
  for (std::size_t i = 0; i < ends.size(); ++i) ends[i] = sums[i] / counts[i];
  const int mode = static_cast<int>(state.range(0));
  NeighbourhoodQuery query;  // the integrator's defaults: 1 cm, k 10, normals
  query.k = mode == 1 ? 0 : 10;
  query.normals = mode != 2;
  SpatialHashGrid grid;
  std::vector<double> knn;
  std::vector<Eigen::Vector3d> normals;
  for (auto _ : state) {
    if (mode == 3) {
      grid.build(ends, query.radius);
      benchmark::DoNotOptimize(grid.cells().data());
    } else {
      analyseNeighbourhoods(ends, query, &knn, &normals, &grid);
      benchmark::DoNotOptimize(knn.data());
      benchmark::DoNotOptimize(normals.data());
    }
  }
  state.counters["points"] = static_cast<double>(ends.size());
  state.counters["cells"] = static_cast<double>(grid.cells().size());
}
BENCHMARK(BM_NeighbourhoodPass)->Arg(0)->Arg(1)->Arg(2)->Arg(3)->Unit(benchmark::kMillisecond);

// Surface extraction from a map holding 50 fruits, each cluster of 5 seen from 6 directions.
static void BM_TsdfExtractSurface(benchmark::State& state) {
  TsdfMap map;
  TsdfIntegratorParams params;
  const TsdfIntegrator integ(params);
  const PointList dirs = fibonacciSphere(6);
  for (int c = 0; c < 10; ++c) {  // 10 clusters of 5 fruits along a 3 m row
    const Eigen::Vector3d center(0.3 * c, 0.6, 0.5);
    const AnalyticScene scene = fruitCluster(center, 5, 100 + c);
    Eigen::Vector3d origin;
    for (const auto& d : dirs) {
      const PinholeCamera cam = PinholeCamera::lookingAt(center + 0.4 * d, center, 320, 240);
      integ.integrate(map, renderDepth(scene, cam).points, cam.position);
    }
  }
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
