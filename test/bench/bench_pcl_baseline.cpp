// The PCL equivalents of the package's NeighbourGrid-based steps, on the same 50-fruit map
// surface as BM_FiftyFruit*: the evidence for keeping the grid (docs/benchmarks.md).
// Run: scripts/run.sh bench --benchmark_filter=FiftyFruit
#include <benchmark/benchmark.h>
#include <fruit_shape_completion/missing_surface.h>
#include <fruit_shape_completion/tsdf_surface.h>

#include <pcl/features/normal_3d_omp.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>

using namespace fruit_shape_completion;

const TsdfMap& fiftyFruitMap();  // bench_tsdf.cpp
const std::vector<std::pair<PointList, Superellipsoid>>& fiftyFruitShapes();

namespace {
pcl::PointCloud<pcl::PointXYZ>::Ptr surfaceCloud() {
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (const auto& p : extractSurfacePoints(fiftyFruitMap()))
    cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())));
  return cloud;
}
}  // namespace

static void BM_FiftyFruitClusteringPcl(benchmark::State& state) {
  const auto cloud = surfaceCloud();
  std::size_t clusters = 0;
  for (auto _ : state) {
    pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
    tree->setInputCloud(cloud);
    pcl::EuclideanClusterExtraction<pcl::PointXYZ> ec;
    ec.setClusterTolerance(0.01);
    ec.setMinClusterSize(100);
    ec.setMaxClusterSize(10000);
    ec.setSearchMethod(tree);
    ec.setInputCloud(cloud);
    std::vector<pcl::PointIndices> found;
    ec.extract(found);
    clusters = found.size();
  }
  state.counters["points"] = static_cast<double>(cloud->size());
  state.counters["clusters"] = static_cast<double>(clusters);
}
BENCHMARK(BM_FiftyFruitClusteringPcl)->Unit(benchmark::kMillisecond);

static void BM_FiftyFruitOutliersPcl(benchmark::State& state) {
  const auto cloud = surfaceCloud();
  for (auto _ : state) {
    pcl::StatisticalOutlierRemoval<pcl::PointXYZ> sor;
    sor.setInputCloud(cloud);
    sor.setMeanK(10);
    sor.setStddevMulThresh(2.0);
    pcl::Indices inliers;
    sor.filter(inliers);
    benchmark::DoNotOptimize(inliers.data());
  }
  state.counters["points"] = static_cast<double>(cloud->size());
}
BENCHMARK(BM_FiftyFruitOutliersPcl)->Unit(benchmark::kMillisecond);

// Arg: threads (NormalEstimationOMP).
static void BM_FiftyFruitNormalsPcl(benchmark::State& state) {
  const auto cloud = surfaceCloud();
  for (auto _ : state) {
    pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> ne(static_cast<unsigned>(state.range(0)));
    ne.setInputCloud(cloud);
    ne.setRadiusSearch(0.015);
    pcl::PointCloud<pcl::Normal> normals;
    ne.compute(normals);
    benchmark::DoNotOptimize(normals.data());
  }
  state.counters["points"] = static_cast<double>(cloud->size());
}
BENCHMARK(BM_FiftyFruitNormalsPcl)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

// The missing-surface test with a kd-tree per fruit (nearest neighbour of each sample).
static void BM_FiftyFruitMissingSurfacePcl(benchmark::State& state) {
  const auto& shapes = fiftyFruitShapes();
  const MissingSurfaceParams params;
  const float t2 = static_cast<float>(params.threshold * params.threshold);
  std::size_t missing = 0;
  for (auto _ : state) {
    missing = 0;
    for (const auto& s : shapes) {
      pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
      for (const auto& p : s.first)
        cloud->push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z())));
      pcl::KdTreeFLANN<pcl::PointXYZ> tree;
      tree.setInputCloud(cloud);
      pcl::Indices nearest(1);
      std::vector<float> d2(1);
      for (const auto& q : s.second.sampleSurface(params.samples)) {
        const pcl::PointXYZ p(static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()));
        if (tree.nearestKSearch(p, 1, nearest, d2) < 1 || d2[0] > t2) ++missing;
      }
    }
  }
  state.counters["fruits"] = static_cast<double>(shapes.size());
  state.counters["missing"] = static_cast<double>(missing);
}
BENCHMARK(BM_FiftyFruitMissingSurfacePcl)->Unit(benchmark::kMillisecond);
