// Benchmarks of the superellipsoid pipeline. Run: scripts/run.sh bench --benchmark_format=json
#include <benchmark/benchmark.h>
#include <fruit_shape_completion/fruit_center.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/superellipsoid_fit.h>
#include <fruit_shape_completion/surface_normals.h>
#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>

using namespace fruit_shape_completion;

namespace {

// A half-seen random fruit with about `target` points (voxel size chosen to get there).
PointList halfSeenFruit(int target, unsigned seed) {
  std::mt19937 rng(seed);
  const Superellipsoid se = randomSuperellipsoid(rng, Eigen::Vector3d(0.3, 0.1, 0.6));
  const SyntheticFruit fruit = SyntheticFruit::fromSuperellipsoid(se);
  ScanParams scan;
  scan.visible_fraction = 0.5;
  scan.view_dir = Eigen::Vector3d(1, 0.3, 0.2);
  scan.seed = seed;
  // Points scale with 1 / voxel^2: adjust the voxel until the count is within 5 % of target.
  PointList pts = scanFruit(fruit, scan);
  for (int i = 0; i < 8 && std::abs(double(pts.size()) - target) > 0.05 * target; ++i) {
    scan.voxel *= std::sqrt(double(pts.size()) / target);
    pts = scanFruit(fruit, scan);
  }
  return pts;
}

}  // namespace

// One fit (normals, centre prior and Ceres LM) of a half-seen fruit.
static void BM_FitFruit(benchmark::State& state) {
  const PointList pts = halfSeenFruit(static_cast<int>(state.range(0)), 3);
  const FitParams params;
  int iterations = 0;
  bool accepted = true;
  for (auto _ : state) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : pts) mean += p;
    mean /= pts.size();
    const SurfaceNormals normals = estimateNormals(pts, NormalParams(), mean);
    const Eigen::Vector3d w = estimateFruitCenter(pts, normals.normals, 2.5);
    const FitResult fit = fitSuperellipsoid(pts, w, params);
    iterations = fit.iterations;
    accepted = accepted && fit.accepted;
    benchmark::DoNotOptimize(fit.shape.a);
  }
  state.counters["points"] = static_cast<double>(pts.size());
  state.counters["lm_iterations"] = iterations;
  state.counters["accepted"] = accepted ? 1 : 0;
  state.SetLabel("half-seen fruit");
}
BENCHMARK(BM_FitFruit)->Arg(300)->Arg(1000)->Arg(3000)->Unit(benchmark::kMillisecond);

// The whole pipeline on a cloud of 10 half-seen fruits (clustering, normals, fits, missing surface).
static void BM_PipelineTenFruits(benchmark::State& state) {
  PointList cloud;
  for (int i = 0; i < 10; ++i) {
    PointList pts = halfSeenFruit(1000, 10 + i);
    for (auto& p : pts) p.x() += 0.2 * i;
    cloud.insert(cloud.end(), pts.begin(), pts.end());
  }
  for (auto _ : state) {
    FruitShapePipeline pipeline;
    benchmark::DoNotOptimize(pipeline.update(cloud).size());
  }
  state.counters["points"] = static_cast<double>(cloud.size());
}
BENCHMARK(BM_PipelineTenFruits)->Unit(benchmark::kMillisecond);

// The data term alone: residuals and the N x 11 Jacobian of a 1000-point cloud.
static void BM_RadialResidualsJacobian(benchmark::State& state) {
  const PointList pts = halfSeenFruit(1000, 3);
  Superellipsoid se;
  se.t = Eigen::Vector3d(0.3, 0.1, 0.6);
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  for (auto _ : state) {
    evaluateRadialResiduals(pts, se, &r, &J);
    benchmark::DoNotOptimize(J.data());
  }
  state.counters["points"] = static_cast<double>(pts.size());
}
BENCHMARK(BM_RadialResidualsJacobian)->Unit(benchmark::kMicrosecond);

// Normals and the centre prior of a 1000-point half-seen fruit.
static void BM_NormalsAndCenter(benchmark::State& state) {
  const PointList pts = halfSeenFruit(1000, 3);
  for (auto _ : state) {
    const SurfaceNormals normals = estimateNormals(pts, NormalParams(), pts.front());
    benchmark::DoNotOptimize(estimateFruitCenter(pts, normals.normals, 2.5));
  }
  state.counters["points"] = static_cast<double>(pts.size());
}
BENCHMARK(BM_NormalsAndCenter)->Unit(benchmark::kMicrosecond);
