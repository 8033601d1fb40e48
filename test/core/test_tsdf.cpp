#include <fruit_shape_completion/instrument/sim/analytic_depth_camera.h>
#include <fruit_shape_completion/euclidean_clustering.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/tsdf_integrator.h>
#include <fruit_shape_completion/tsdf_surface.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <tuple>
#include <unordered_set>
#include <thread>
#include <sys/wait.h>
#include <unistd.h>

using namespace fruit_shape_completion;

namespace {

Superellipsoid sphere(double r, const Eigen::Vector3d& c) { return Superellipsoid::sphere(r, c); }

// A small camera (160 x 120, same 80 degree field of view) keeps the tests quick; the map
// sees ~1.5 mm pixel spacing at 0.35 m, several points per 4 mm voxel, as a VGA camera at 0.7 m.
PinholeCamera cameraAround(const Eigen::Vector3d& target, const Eigen::Vector3d& dir, double dist) {
  return PinholeCamera::lookingAt(target + dist * dir.normalized(), target, 160, 120);
}

// Integrates views of `scene` from `n` directions around `target` (Fibonacci sphere, or a ring
// in the horizontal plane when ring is true). Only points of shapes (not planes) are integrated,
// as a fruit mask would cut them out.
// One view of the scene's shapes (not its planes) from `cam` into the map.
IntegrationReport integrateFruitView(TsdfMap& map, const TsdfIntegrator& integ, const AnalyticScene& scene,
                                     const PinholeCamera& cam, double noise, unsigned seed) {
  const DepthScan scan = renderDepth(scene, cam, noise, seed);
  PointList fruit;
  for (std::size_t k = 0; k < scan.points.size(); ++k)
    if (scan.labels[k] < static_cast<int>(scene.shapes.size())) fruit.push_back(scan.points[k]);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = cam.rotation;
  pose.translation() = cam.position;
  return integ.integrate(map, fruit, pose);
}

void integrateViews(TsdfMap& map, const TsdfIntegrator& integ, const AnalyticScene& scene,
                    const Eigen::Vector3d& target, int n, double noise = 0.0, unsigned seed = 1) {
  const PointList dirs = fibonacciSphere(n);
  for (int i = 0; i < n; ++i) {
    const IntegrationReport r = integrateFruitView(map, integ, scene, cameraAround(target, dirs[i], 0.35), noise, seed + i);
    ASSERT_TRUE(r.ok()) << r.error;
  }
}

double coverage(const PointList& surface, const Superellipsoid& truth, double radius) {
  const PointList samples = truth.sampleSurface(3000);
  int covered = 0;
  for (const auto& s : samples)
    covered += std::any_of(surface.begin(), surface.end(), [&](const Point& p) { return (p - s).norm() <= radius; });
  return static_cast<double>(covered) / samples.size();
}

double rmsError(const PointList& pts, const Superellipsoid& truth) {
  double sum = 0;
  for (const auto& p : pts) sum += std::pow(truth.radialDistance(p), 2);
  return std::sqrt(sum / pts.size());
}

// The two maps hold the same blocks, in the same order, and the same voxels to the bit.
void expectSameMap(const TsdfMap& a, const TsdfMap& b) {
  ASSERT_EQ(a.blockCount(), b.blockCount());
  ASSERT_EQ(a.observedVoxelCount(), b.observedVoxelCount());
  std::vector<VoxelIndex> order_a, order_b;
  b.forEachBlock([&](const TsdfBlock& block) { order_b.push_back(block.origin); });
  std::size_t differing = 0;
  a.forEachBlock([&](const TsdfBlock& block) {
    order_a.push_back(block.origin);
    block.forEachObserved([&](std::uint32_t idx) {
      const TsdfVoxel& va = block.voxels[idx];
      const TsdfVoxel* vb = b.voxel(block.origin + block.coordsOf(idx).cast<std::int64_t>());
      differing += (vb == nullptr || va.distance != vb->distance || va.weight != vb->weight) ? 1 : 0;
    });
  });
  EXPECT_EQ(order_a, order_b);
  EXPECT_EQ(differing, 0u);
}

// The blocks' observed bits mark exactly the voxels that hold weight.
void expectObservedExactlyWhereWeighted(const TsdfMap& map) {
  std::size_t mismatches = 0, observed = 0;
  map.forEachBlock([&](const TsdfBlock& block) {
    std::vector<char> listed(block.voxelCount(), 0);
    block.forEachObserved([&](std::uint32_t idx) { listed[idx] = 1; });
    for (std::uint32_t idx = 0; idx < block.voxelCount(); ++idx) {
      observed += listed[idx];
      mismatches += (block.voxels[idx].weight > 0.0f) != (listed[idx] != 0);
    }
  });
  EXPECT_EQ(mismatches, 0u);
  EXPECT_EQ(observed, map.observedVoxelCount());
}

}  // namespace

// 14 views from all around: the surface lies within a voxel of the truth, covers >= 95 % of it,
// and the fit of it recovers the volume within 3 % and the centre within 2 mm.
TsdfMap checkAllAroundReconstruction(const Superellipsoid& truth, const char* name) {
  AnalyticScene scene;
  scene.shapes.push_back(truth);
  TsdfMap map;
  integrateViews(map, TsdfIntegrator(), scene, truth.t, 14);
  const PointList surface = extractSurfacePoints(map);
  EXPECT_GT(surface.size(), 500u);
  double worst = 0;
  for (const auto& p : surface) worst = std::max(worst, truth.radialDistance(p));
  EXPECT_LT(worst, map.voxelSize());
  const double cov = coverage(surface, truth, map.voxelSize());
  EXPECT_GE(cov, 0.95);
  FruitShapePipeline pipeline;
  const auto& fruits = pipeline.update(surface);
  EXPECT_EQ(fruits.size(), 1u);
  if (fruits.size() != 1u) return map;
  EXPECT_TRUE(fruits[0].accepted) << fruits[0].reason;
  EXPECT_NEAR(fruits[0].volume, truth.volume(), 0.03 * truth.volume());
  EXPECT_LT((fruits[0].center() - truth.t).norm(), 0.002);
  std::printf("[ report   ] %s: %zu surface points, worst error %.2f mm, rms %.2f mm, coverage %.3f, "
              "volume accuracy %.4f\n", name, surface.size(), worst * 1000,
              rmsError(surface, truth) * 1000, cov,
              1 - std::abs(fruits[0].volume - truth.volume()) / truth.volume());
  return map;
}

TEST(TsdfMap, SphereFromAllAroundIsAccurateCompleteAndFitsItsVolume) {
  checkAllAroundReconstruction(sphere(0.04, Eigen::Vector3d(0.1, 0.2, 0.5)), "sphere");
}

TEST(TsdfMap, PosedSuperellipsoidFromAllAround) {
  Superellipsoid truth;
  truth.a = 0.035; truth.b = 0.045; truth.c = 0.05; truth.e1 = 0.6; truth.e2 = 0.8;
  truth.t = Eigen::Vector3d(-0.2, 0.4, 0.6);
  truth.rpy = Eigen::Vector3d(0.4, -0.3, 1.1);
  const TsdfMap map = checkAllAroundReconstruction(truth, "superellipsoid");
  // Projected onto the zero crossing: also within a voxel, and with a smaller RMS error.
  SurfaceExtractionParams projected;
  projected.project_to_zero_crossing = true;
  const PointList proj = extractSurfacePoints(map, projected);
  double worst_proj = 0;
  for (const auto& p : proj) worst_proj = std::max(worst_proj, truth.radialDistance(p));
  EXPECT_LT(worst_proj, map.voxelSize());
  EXPECT_LT(rmsError(proj, truth), 0.7 * rmsError(extractSurfacePoints(map), truth));
}

TEST(TsdfMap, TheSameViewTwiceDoesNotMoveTheSurface) {
  const Superellipsoid truth = sphere(0.04, Eigen::Vector3d(0, 0, 0.5));
  AnalyticScene scene;
  scene.shapes.push_back(truth);
  TsdfMap map;
  const TsdfIntegrator integ;
  integrateViews(map, integ, scene, truth.t, 1);
  const PointList once = extractSurfacePoints(map);
  integrateViews(map, integ, scene, truth.t, 1);
  const PointList twice = extractSurfacePoints(map);
  ASSERT_EQ(once.size(), twice.size());
  double moved = 0;
  for (std::size_t i = 0; i < once.size(); ++i) moved = std::max(moved, (once[i] - twice[i]).norm());
  EXPECT_LT(moved, 1e-6);
}

TEST(TsdfMap, NoisyViewsAverageOut) {
  const Superellipsoid truth = sphere(0.04, Eigen::Vector3d(0, 0, 0.5));
  AnalyticScene scene;
  scene.shapes.push_back(truth);
  const double noise = 0.02;  // 2.5 mm at 0.35 m
  TsdfIntegratorParams params;
  params.remove_outliers = false;
  const TsdfIntegrator integ(params);
  const PointList dir = {Eigen::Vector3d(1, 0.2, 0.3)};
  auto viewOnce = [&](TsdfMap& map, unsigned seed) {
    const PinholeCamera cam = cameraAround(truth.t, dir[0], 0.35);
    const DepthScan scan = renderDepth(scene, cam, noise, seed);
    ASSERT_TRUE(integ.integrate(map, scan.points, cam.position).ok());
  };
  TsdfMap exact, single, ten;
  {
    const PinholeCamera cam = cameraAround(truth.t, dir[0], 0.35);
    ASSERT_TRUE(integ.integrate(exact, renderDepth(scene, cam).points, cam.position).ok());
  }
  viewOnce(single, 100);
  for (unsigned s = 0; s < 10; ++s) viewOnce(ten, 200 + s);
  // The noise-free view has an error of its own (voxels at the silhouette); the noise adds
  // variance on top, and ten views must remove most of that added variance (1/10 ideally).
  // Measured on the zero crossing (projected), not on voxel centres, whose 4 mm quantisation
  // would hide the noise.
  SurfaceExtractionParams zero;
  zero.project_to_zero_crossing = true;
  const double e0 = rmsError(extractSurfacePoints(exact, zero), truth);
  const double e1 = rmsError(extractSurfacePoints(single, zero), truth);
  const double e10 = rmsError(extractSurfacePoints(ten, zero), truth);
  std::printf("[ report   ] surface rms error: noise-free view %.2f mm, 1 noisy view %.2f mm, 10 noisy "
              "views %.2f mm\n", e0 * 1000, e1 * 1000, e10 * 1000);
  EXPECT_GT(e1, 1.5 * e0);  // the noise matters
  EXPECT_LT(e10 * e10 - e0 * e0, 0.3 * (e1 * e1 - e0 * e0));
}

TEST(TsdfMap, TwoFruitsOneAndAHalfCentimetresApartStayTwoSurfaces) {
  AnalyticScene scene;
  scene.shapes.push_back(sphere(0.04, Eigen::Vector3d(0, 0, 0.5)));
  scene.shapes.push_back(sphere(0.035, Eigen::Vector3d(0.09, 0, 0.5)));  // gap 1.5 cm
  TsdfMap map;
  integrateViews(map, TsdfIntegrator(), scene, Eigen::Vector3d(0.045, 0, 0.5), 14);
  const PointList surface = extractSurfacePoints(map);
  const auto clusters = euclideanClusters(surface, ClusteringParams());
  ASSERT_EQ(clusters.size(), 2u);
  for (const auto& p : surface) {
    const double d0 = std::abs((p - scene.shapes[0].t).norm() - 0.04);
    const double d1 = std::abs((p - scene.shapes[1].t).norm() - 0.035);
    EXPECT_LT(std::min(d0, d1), map.voxelSize());  // nothing glued in the gap
  }
}

TEST(TsdfMap, MeshLiesOnTheSurfaceAndFacesOutward) {
  const Superellipsoid truth = sphere(0.04, Eigen::Vector3d(0.05, 0.05, 0.5));
  AnalyticScene scene;
  scene.shapes.push_back(truth);
  TsdfMap map;
  integrateViews(map, TsdfIntegrator(), scene, truth.t, 14);
  const TriangleMesh mesh = extractSurfaceMesh(map);
  ASSERT_GT(mesh.triangles.size(), 1000u);
  int outward = 0;
  double worst = 0;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.vertices[t.x()].cast<double>(), b = mesh.vertices[t.y()].cast<double>(),
                          c = mesh.vertices[t.z()].cast<double>();
    outward += (b - a).cross(c - a).dot((a + b + c) / 3 - truth.t) > 0;
    for (const auto* v : {&a, &b, &c}) worst = std::max(worst, std::abs((*v - truth.t).norm() - truth.a));
  }
  EXPECT_LT(worst, map.voxelSize());
  EXPECT_GT(outward, 0.99 * mesh.triangles.size());
  const std::string path = "/tmp/fsc_mesh_" + std::to_string(::getpid()) + ".ply";
  std::string err;
  EXPECT_TRUE(mesh.writePly(path, &err)) << err;
  std::remove(path.c_str());
}

TEST(TsdfMap, SaveAndLoadRestoreTheMapAndRefuseBrokenFiles) {
  const Superellipsoid truth = sphere(0.04, Eigen::Vector3d(-0.3, 0.1, 0.5));
  AnalyticScene scene;
  scene.shapes.push_back(truth);
  TsdfMap map;
  integrateViews(map, TsdfIntegrator(), scene, truth.t, 3);
  const std::string path = "/tmp/fsc_map_" + std::to_string(::getpid()) + ".tsdf";
  std::string err;
  ASSERT_TRUE(map.save(path, &err)) << err;
  TsdfMap loaded;
  ASSERT_TRUE(loaded.load(path, &err)) << err;
  EXPECT_EQ(loaded.blockCount(), map.blockCount());
  EXPECT_EQ(loaded.observedVoxelCount(), map.observedVoxelCount());
  expectObservedExactlyWhereWeighted(loaded);
  const PointList a = extractSurfacePoints(map), b = extractSurfacePoints(loaded);
  EXPECT_EQ(a.size(), b.size());
  EXPECT_LT(std::abs(rmsError(a, truth) - rmsError(b, truth)), 1e-9);
  // A truncated file and a foreign file: refused, the map keeps what it had.
  {
    std::ifstream in(path, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(path, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  const std::size_t before = loaded.observedVoxelCount();
  EXPECT_FALSE(loaded.load(path, &err));
  EXPECT_NE(err.find("truncated"), std::string::npos) << err;
  std::ofstream(path) << "hello";
  EXPECT_FALSE(loaded.load(path, &err));
  EXPECT_NE(err.find("magic"), std::string::npos) << err;
  // Lying headers and block origins far beyond any real map: refused.
  {
    TsdfMap far;
    TsdfVoxel v;
    v.distance = 0.0f;
    v.weight = 1.0f;
    ASSERT_TRUE(far.setVoxel(VoxelIndex(1, 2, 3), v));
    // Saves `far`, overwrites the bytes at `offset` with `value`, and expects load to refuse it
    // with a message containing `expected`. Header: magic 8, version 4, voxel size 8, vps 4,
    // count 8; then the first block's origin (3 x int64).
    auto refusedWhenPatched = [&](std::streamoff offset, const auto& value, const std::string& expected) {
      ASSERT_TRUE(far.save(path, &err)) << err;
      std::fstream io(path, std::ios::in | std::ios::out | std::ios::binary);
      io.seekp(offset);
      io.write(reinterpret_cast<const char*>(&value), sizeof(value));
      io.close();
      EXPECT_FALSE(loaded.load(path, &err));
      EXPECT_NE(err.find(expected), std::string::npos) << err;
    };
    refusedWhenPatched(8 + 4 + 8 + 4 + 8, std::int64_t(1) << 50, "out of range");
    refusedWhenPatched(8 + 4, 1e-300, "voxel_size");
    refusedWhenPatched(8 + 4 + 8, std::uint32_t(512), "exceeds 128");  // 1 GiB blocks
    refusedWhenPatched(8 + 4 + 8 + 4 + 8, std::numeric_limits<std::int64_t>::min(), "out of range");
  }
  EXPECT_EQ(loaded.observedVoxelCount(), before);
  std::remove(path.c_str());
}

// A file's block side replaces the map's, and the budget then holds that many of its blocks:
// 64-voxel blocks (2 MiB) in a map made for 16 (32 KiB) must not get the smaller blocks' count.
TEST(TsdfMap, LoadingAnotherBlockSideKeepsTheMemoryBudget) {
  TsdfMapParams paper_blocks;
  paper_blocks.voxels_per_side = 64;
  TsdfMap saved(paper_blocks);
  TsdfVoxel v;
  v.distance = 0.001f;
  v.weight = 1.0f;
  ASSERT_TRUE(saved.setVoxel(VoxelIndex(1, 2, 3), v));
  const std::string path = "/tmp/fsc_map_side_" + std::to_string(::getpid()) + ".tsdf";
  std::string err;
  ASSERT_TRUE(saved.save(path, &err)) << err;
  TsdfMapParams small_blocks;
  small_blocks.voxels_per_side = 16;
  small_blocks.memory_budget_mb = 5.0;  // 160 blocks of 16, 2 of 64
  TsdfMap map(small_blocks);
  ASSERT_TRUE(map.load(path, &err)) << err;
  std::remove(path.c_str());
  EXPECT_EQ(map.voxelsPerSide(), 64);
  EXPECT_EQ(map.params().maxBlocks(), 2u);
  EXPECT_FALSE(map.atBudget());
  EXPECT_TRUE(map.setVoxel(VoxelIndex(1000, 2, 3), v));  // a second block: the budget's last
  EXPECT_TRUE(map.atBudget());
  EXPECT_FALSE(map.setVoxel(VoxelIndex(2000, 2, 3), v));
  // A reset's empty map is the configured one again: 16-voxel blocks, over a hundred of them.
  map.clear();
  EXPECT_EQ(map.voxelsPerSide(), 16);
  EXPECT_EQ(map.params().maxBlocks(), small_blocks.maxBlocks());
  EXPECT_GT(map.params().maxBlocks(), 100u);
  EXPECT_TRUE(map.setVoxel(VoxelIndex(1000, 2, 3), v));
  EXPECT_TRUE(map.setVoxel(VoxelIndex(2000, 2, 3), v));
  EXPECT_EQ(map.blockCount(), 2u);
  EXPECT_LE(map.memoryBytes(), static_cast<std::size_t>(5.0 * 1048576.0));
}

TEST(TsdfMap, MemoryCropBoxBlockLimitAndReset) {
  AnalyticScene scene;
  scene.shapes.push_back(sphere(0.04, Eigen::Vector3d(0, 0, 0.5)));
  scene.shapes.push_back(sphere(0.04, Eigen::Vector3d(0.5, 0, 0.5)));
  TsdfMapParams crop;
  crop.use_crop_box = true;
  crop.crop_min = Eigen::Vector3d(-0.2, -0.2, 0.2);
  crop.crop_max = Eigen::Vector3d(0.2, 0.2, 0.8);
  crop.voxels_per_side = 64;  // the paper's blocks: the sizes below are worked out for them
  TsdfMapParams paper_blocks;
  paper_blocks.voxels_per_side = 64;
  TsdfMap cropped(crop), full(paper_blocks);
  integrateViews(cropped, TsdfIntegrator(), scene, Eigen::Vector3d(0.25, 0, 0.5), 6);
  integrateViews(full, TsdfIntegrator(), scene, Eigen::Vector3d(0.25, 0, 0.5), 6);
  for (const auto& p : extractSurfacePoints(cropped)) EXPECT_LT(p.x(), 0.2 + 1e-9);
  EXPECT_LT(cropped.memoryBytes(), full.memoryBytes());
  EXPECT_GE(full.memoryBytes(), full.blockCount() * 64 * 64 * 64 * sizeof(TsdfVoxel));
  TsdfMapParams limited = paper_blocks;
  limited.memory_budget_mb = 3.0;  // one 2 MiB block
  TsdfMap small(limited);
  integrateViews(small, TsdfIntegrator(), scene, Eigen::Vector3d(0.25, 0, 0.5), 2);
  EXPECT_EQ(small.blockCount(), 1u);
  full.clear();
  EXPECT_EQ(full.blockCount(), 0u);
  EXPECT_TRUE(extractSurfacePoints(full).empty());
}

TEST(TsdfMap, BadInputIsRefusedWithAMessageAndTheMapKept) {
  const Superellipsoid truth = sphere(0.04, Eigen::Vector3d(0, 0, 0.5));
  AnalyticScene scene;
  scene.shapes.push_back(truth);
  TsdfMap map;
  const TsdfIntegrator integ;
  integrateViews(map, integ, scene, truth.t, 2);
  const std::size_t observed = map.observedVoxelCount();
  const PointList surface = extractSurfacePoints(map);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const Eigen::Vector3d origin(0.4, 0, 0.5);

  IntegrationReport r = integ.integrate(map, {}, origin);
  EXPECT_FALSE(r.ok());
  EXPECT_NE(r.error.find("empty"), std::string::npos);
  r = integ.integrate(map, surface, Eigen::Vector3d(nan, 0, 0));
  EXPECT_FALSE(r.ok());
  EXPECT_NE(r.error.find("not finite"), std::string::npos);
  Eigen::Isometry3d bad_pose = Eigen::Isometry3d::Identity();
  bad_pose.linear()(0, 0) = nan;
  EXPECT_FALSE(integ.integrate(map, surface, bad_pose).ok());
  PointList huge(2000001, Eigen::Vector3d(0, 0, 0.5));
  r = integ.integrate(map, huge, origin);
  EXPECT_FALSE(r.ok());
  EXPECT_NE(r.error.find("max_points"), std::string::npos) << r.error;
  huge.clear();
  huge.shrink_to_fit();
  // Only bad points: all skipped and counted, with a warning.
  const PointList bad = {Eigen::Vector3d(nan, 0, 0), Eigen::Vector3d(0, inf, 0), origin,
                         origin + Eigen::Vector3d(0, 0, 1e-4), origin + Eigen::Vector3d(10, 0, 0)};
  r = integ.integrate(map, bad, origin);
  EXPECT_TRUE(r.ok());
  EXPECT_EQ(r.non_finite, 2u);
  EXPECT_EQ(r.out_of_range, 3u);
  EXPECT_EQ(r.rays, 0u);
  EXPECT_FALSE(r.warning.empty());
  EXPECT_EQ(map.observedVoxelCount(), observed);
  // Behind the sensor: a camera at the origin looking along +x sees nothing at x < 0.
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;  // optical z along world +x
  pose.translation() = Eigen::Vector3d(0.5, 0, 0.5);
  r = integ.integrate(map, {Eigen::Vector3d(0.1, 0, 0.5), Eigen::Vector3d(0.2, 0.01, 0.5)}, pose);
  EXPECT_EQ(r.out_of_range, 2u);
  EXPECT_EQ(map.observedVoxelCount(), observed);
  // A sensor beyond 1e4 m (here one key period of the map away, where it would fold onto the
  // blocks near the origin that share its hash key): refused as a whole.
  const Eigen::Vector3d far(64.0 * 0.004 * (1 << 21), 0, 0);
  r = integ.integrate(map, {far + Eigen::Vector3d(0.1, 0.6, 0.5)}, far + Eigen::Vector3d(0.1, 0.2, 0.5));
  EXPECT_NE(r.error.find("beyond 1e4 m"), std::string::npos) << r.error;
  EXPECT_EQ(map.observedVoxelCount(), observed);
  // Points beyond 1e4 m seen from a sane pose are out of range, counted.
  r = integ.integrate(map, {Eigen::Vector3d(2e4, 0, 0.5), Eigen::Vector3d(0.1, 0.6, 0.5)}, Eigen::Vector3d(0.1, 0.2, 0.5));
  EXPECT_EQ(r.out_of_range, 1u);
  TsdfIntegratorParams tiny;
  tiny.max_weight = 1e-30;
  EXPECT_THROW(TsdfIntegrator{tiny}, std::invalid_argument);
  TsdfIntegratorParams far_range;
  far_range.max_range = 1e6;  // carving would step through every voxel of such a ray
  EXPECT_THROW(TsdfIntegrator{far_range}, std::invalid_argument);
}

// One const integrator used by two threads at once (each into its own map): both maps equal
// those of lone calls.
TEST(TsdfMap, OneIntegratorServesTwoThreadsAtOnce) {
  AnalyticScene scene;
  scene.shapes.push_back(sphere(0.04, Eigen::Vector3d(0.0, 0.5, 0.5)));
  const PinholeCamera cam = PinholeCamera::lookingAt(Eigen::Vector3d(0, 0.1, 0.5), Eigen::Vector3d(0, 0.5, 0.5));
  const PointList frame = renderDepth(scene, cam).points;
  const TsdfIntegrator integ;
  TsdfMap reference;
  for (int rep = 0; rep < 5; ++rep) ASSERT_TRUE(integ.integrate(reference, frame, cam.position).ok());
  const PointList expected = extractSurfacePoints(reference);
  ASSERT_GT(expected.size(), 300u);  // the visible half of the sphere
  PointList got[2];
  std::thread other([&] {
    TsdfMap m;
    for (int rep = 0; rep < 5; ++rep) integ.integrate(m, frame, cam.position);
    got[1] = extractSurfacePoints(m);
  });
  TsdfMap m;
  for (int rep = 0; rep < 5; ++rep) integ.integrate(m, frame, cam.position);
  got[0] = extractSurfacePoints(m);
  other.join();
  for (const PointList& g : got) {  // the same arithmetic: the same surface, to the bit
    ASSERT_EQ(g.size(), expected.size());
    for (std::size_t k = 0; k < g.size(); ++k) ASSERT_EQ(g[k], expected[k]) << k;
  }
}

// The block side does not change what is mapped; files keep the x-fastest voxel index.
TEST(TsdfMap, BlockSideDoesNotChangeTheMap) {
  AnalyticScene scene;
  scene.shapes.push_back(sphere(0.04, Eigen::Vector3d(0.0, 0.5, 0.5)));
  scene.planes.push_back({Eigen::Vector3d(0, 1.0, 0), Eigen::Vector3d(0, -1, 0)});
  const PinholeCamera cam = PinholeCamera::lookingAt(Eigen::Vector3d(0, 0, 0.5), Eigen::Vector3d(0, 1, 0.5), 320, 240);
  const PointList frame = renderDepth(scene, cam, 0.001, 5).points;
  TsdfMapParams plain, linear;
  linear.voxels_per_side = 48;  // not a power of two: other block borders
  auto surfaceOf = [&](const TsdfMapParams& p) {
    TsdfMap map(p);
    const IntegrationReport r = TsdfIntegrator().integrate(map, frame, cam.position);
    EXPECT_TRUE(r.ok()) << r.error;
    PointList s = extractSurfacePoints(map);
    std::sort(s.begin(), s.end(), [](const Point& a, const Point& b) {
      return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
    });
    return s;
  };
  const PointList a = surfaceOf(plain), c = surfaceOf(linear);
  ASSERT_GT(a.size(), 5000u);
  ASSERT_EQ(a.size(), c.size());
  for (std::size_t i = 0; i < a.size(); ++i) ASSERT_LT((a[i] - c[i]).norm(), 1e-12) << i;

  TsdfMapParams paper_blocks;
  paper_blocks.voxels_per_side = 64;  // the index below is worked out for 64-voxel blocks
  TsdfMap one(paper_blocks);
  TsdfVoxel v;
  v.distance = 0.001f;
  v.weight = 2.0f;
  ASSERT_TRUE(one.setVoxel(VoxelIndex(1, 2, 3), v));
  const std::string path = "/tmp/fsc_layout_" + std::to_string(::getpid()) + ".tsdf";
  std::string err;
  ASSERT_TRUE(one.save(path, &err)) << err;
  std::ifstream in(path, std::ios::binary);
  in.seekg(8 + 4 + 8 + 4 + 8 + 3 * 8 + 4);  // header, block origin, voxel count
  std::uint32_t idx = 0;
  in.read(reinterpret_cast<char*>(&idx), 4);
  EXPECT_EQ(idx, 1u + 64u * (2u + 64u * 3u));
  TsdfMap back;
  ASSERT_TRUE(back.load(path, &err)) << err;
  const TsdfVoxel* got = back.voxel(VoxelIndex(1, 2, 3));
  ASSERT_NE(got, nullptr);
  EXPECT_EQ(got->weight, 2.0f);
  EXPECT_EQ(back.observedVoxelCount(), 1u);
  // A file of another block side (a power of two and not) loads into a default map, which then
  // finds and extends its voxels with that side.
  for (int side : {16, 12}) {
    TsdfMapParams mp;
    mp.voxels_per_side = side;
    TsdfMap other(mp);
    ASSERT_TRUE(other.setVoxel(VoxelIndex(40, -20, 70), v));
    ASSERT_TRUE(other.save(path, &err)) << err;
    TsdfMap into;
    ASSERT_TRUE(into.load(path, &err)) << err;
    EXPECT_EQ(into.voxelsPerSide(), side);
    const TsdfVoxel* found = into.voxel(VoxelIndex(40, -20, 70));
    ASSERT_NE(found, nullptr) << side;
    EXPECT_EQ(found->weight, 2.0f);
    ASSERT_TRUE(into.setVoxel(VoxelIndex(41, -20, 70), v));
    EXPECT_EQ(into.blockCount(), 1u) << side;  // the neighbour lies in the same block
    EXPECT_EQ(into.observedVoxelCount(), 2u);
  }
  std::remove(path.c_str());
}

// At the memory budget the map keeps what it has: the fruit mapped first keeps updating, a
// second fruit that needs new blocks is dropped, and the report counts and says so.
TEST(TsdfMap, AtItsMemoryBudgetNewBlocksAreRefusedCountedAndReported) {
  TsdfMapParams params;
  params.voxels_per_side = 64;     // the paper's 25.6 cm blocks, as the positions below assume
  params.memory_budget_mb = 5.0;  // two 2 MiB blocks
  EXPECT_EQ(params.maxBlocks(), 2u);
  TsdfMap map(params);
  // A fruit inside one block (blocks are 25.6 cm; this one spans [0, 0.256) on every axis).
  const Superellipsoid first = sphere(0.03, Eigen::Vector3d(0.128, 0.128, 0.128));
  AnalyticScene scene;
  scene.shapes.push_back(first);
  const TsdfIntegrator integ;
  const PinholeCamera cam = cameraAround(first.t, Eigen::Vector3d(0.3, -1, 0.2), 0.22);
  const DepthScan scan = renderDepth(scene, cam, 0.0, 1);
  IntegrationReport r = integ.integrate(map, scan.points, cam.position);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.over_budget, 0u);
  EXPECT_LE(map.blockCount(), 2u);
  // Fill the budget, then a fruit 2 m away needs blocks the budget does not hold.
  map.blockForUpdate(VoxelIndex(64 * 5, 0, 0));
  map.blockForUpdate(VoxelIndex(64 * 6, 0, 0));
  ASSERT_TRUE(map.atBudget());
  const std::size_t blocks = map.blockCount();
  const std::size_t observed = map.observedVoxelCount();
  AnalyticScene far;
  far.shapes.push_back(sphere(0.03, Eigen::Vector3d(2.128, 0.128, 0.128)));
  const PinholeCamera far_cam = cameraAround(far.shapes[0].t, Eigen::Vector3d(0.3, -1, 0.2), 0.3);
  r = integ.integrate(map, renderDepth(far, far_cam, 0.0, 2).points, far_cam.position);
  EXPECT_TRUE(r.ok()) << r.error;
  EXPECT_GT(r.over_budget, 100u);
  EXPECT_EQ(r.over_budget, r.rays);
  EXPECT_NE(r.warning.find("memory budget"), std::string::npos) << r.warning;
  EXPECT_EQ(map.blockCount(), blocks);
  EXPECT_EQ(map.observedVoxelCount(), observed);
  // The first fruit, already mapped, still updates.
  r = integ.integrate(map, scan.points, cam.position);
  EXPECT_EQ(r.over_budget, 0u);
  EXPECT_GT(r.voxel_updates, 0u);
  TsdfMapParams none = params;
  none.memory_budget_mb = 1.0;  // less than a 2 MiB block
  EXPECT_THROW(TsdfMap{none}, std::invalid_argument);

  // A full map with a crop box: what lies outside the box is counted as outside the map, not as
  // over the budget (raising the budget would not bring it in).
  TsdfMapParams cropped = params;
  cropped.use_crop_box = true;
  cropped.crop_min = Eigen::Vector3d(-1, -1, -1);
  cropped.crop_max = Eigen::Vector3d(1, 1, 1);
  TsdfMap boxed(cropped);
  boxed.blockForUpdate(VoxelIndex(0, 0, 0));
  boxed.blockForUpdate(VoxelIndex(64, 0, 0));
  ASSERT_TRUE(boxed.atBudget());
  r = integ.integrate(boxed, renderDepth(far, far_cam, 0.0, 2).points, far_cam.position);
  EXPECT_EQ(r.over_budget, 0u);
  EXPECT_GT(r.outside_map, 100u);
  EXPECT_EQ(r.warning.find("memory budget"), std::string::npos) << r.warning;
}

// Every block side a map accepts is one its saved file can be loaded with; one beyond is refused
// when the map is made, not when its file is read back.
TEST(TsdfMap, EveryAcceptedBlockSideLoadsBack) {
  const std::string path = "/tmp/fsc_block_side_" + std::to_string(::getpid()) + ".tsdf";
  std::string err;
  for (const int side : {1, 48, TsdfMapParams::kMaxVoxelsPerSide}) {
    TsdfMapParams p;
    p.voxels_per_side = side;
    TsdfMap map(p);
    ASSERT_TRUE(map.setVoxel(VoxelIndex(3, -2, side + 1), {0.001f, 1.0f}));
    ASSERT_TRUE(map.save(path, &err)) << err;
    TsdfMap loaded(p);
    EXPECT_TRUE(loaded.load(path, &err)) << "side " << side << ": " << err;
    EXPECT_EQ(loaded.observedVoxelCount(), 1u) << "side " << side;
  }
  TsdfMapParams beyond;
  beyond.voxels_per_side = TsdfMapParams::kMaxVoxelsPerSide + 1;
  EXPECT_THROW(TsdfMap{beyond}, std::invalid_argument);
  std::remove(path.c_str());
}

// save() replaces the file atomically: a process killed (SIGKILL) at any moment of a large save
// leaves either the previous map or the complete new one, never a truncated file.
TEST(TsdfMap, KilledDuringASaveTheFileHoldsTheOldMapOrTheNew) {
  TsdfMap small, large;
  for (int i = 0; i < 1000; ++i) ASSERT_TRUE(small.setVoxel(VoxelIndex(i % 10, i / 10 % 10, i / 100), {0.001f, 1.0f}));
  // Eight fully observed blocks: a file of ~25 MB, written over tens of milliseconds.
  const int n = large.voxelsPerSide();
  for (int b = 0; b < 8; ++b)
    for (int x = 0; x < n; ++x)
      for (int y = 0; y < n; ++y)
        for (int z = 0; z < n; ++z) ASSERT_TRUE(large.setVoxel(VoxelIndex(b * n + x, y, z), {0.002f, 2.0f}));
  const std::string path = "/tmp/fsc_killed_save_" + std::to_string(::getpid()) + ".tsdf";
  std::string err;
  ASSERT_TRUE(small.save(path, &err)) << err;
  int saw_old = 0, saw_new = 0;
  for (int round = 0; round < 8; ++round) {
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      for (;;) large.save(path, nullptr);  // until killed
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20 + 37 * round));
    ::kill(child, SIGKILL);
    int status = 0;
    ::waitpid(child, &status, 0);
    TsdfMap loaded;
    ASSERT_TRUE(loaded.load(path, &err)) << "round " << round << ": " << err;
    const std::size_t observed = loaded.observedVoxelCount();
    EXPECT_TRUE(observed == small.observedVoxelCount() || observed == large.observedVoxelCount()) << observed;
    saw_old += observed == small.observedVoxelCount();
    saw_new += observed == large.observedVoxelCount();
  }
  std::printf("[ report   ] killed mid-save 8 times: %d times the old map, %d times the new, 0 broken\n", saw_old, saw_new);
  // A save that cannot complete (no such directory) fails with a message and leaves nothing.
  EXPECT_FALSE(large.save("/nonexistent_dir_fsc/map.tsdf", &err));
  EXPECT_NE(err.find("/nonexistent_dir_fsc/map.tsdf"), std::string::npos);
  std::remove(path.c_str());
  // A killed save leaves its temporary file beside the target (the target itself is intact).
  const std::string pattern = path + ".tmp";
  for (const auto& entry : std::filesystem::directory_iterator("/tmp"))
    if (entry.path().string().rfind(pattern, 0) == 0) std::filesystem::remove(entry.path());
}

// Two fruits a metre apart lie in different blocks: a view of one leaves the other's blocks
// unchanged, and only the changed blocks are extracted again; the points equal a full
// extraction's after every view, after a reset and with projection on.
TEST(TsdfMap, IncrementalSurfaceExtractionTouchesOnlyChangedBlocks) {
  AnalyticScene near_scene, far_scene;
  near_scene.shapes.push_back(sphere(0.04, Eigen::Vector3d(0, 0, 0.5)));
  far_scene.shapes.push_back(sphere(0.04, Eigen::Vector3d(1.0, 0, 0.5)));
  for (const bool project : {false, true}) {
    SurfaceExtractionParams params;
    params.project_to_zero_crossing = project;
    TsdfMap map;
    const TsdfIntegrator integ;
    IncrementalSurfaceExtractor incremental(params);
    auto expectSame = [&]() {
      const PointList got = incremental.extract(map);
      const PointList full = extractSurfacePoints(map, params);
      ASSERT_EQ(got.size(), full.size());
      ASSERT_FALSE(full.empty());
      for (std::size_t i = 0; i < full.size(); ++i) ASSERT_EQ(got[i], full[i]) << "point " << i;
    };
    integrateViews(map, integ, near_scene, near_scene.shapes[0].t, 3);
    integrateViews(map, integ, far_scene, far_scene.shapes[0].t, 3);
    expectSame();
    EXPECT_EQ(incremental.lastBlocksExtracted(), map.blockCount());
    const std::size_t blocks = map.blockCount();
    const SurfaceBlocks before = incremental.lastBlocks();
    integrateViews(map, integ, near_scene, near_scene.shapes[0].t, 1, 0.0, 7);
    expectSame();
    EXPECT_GE(incremental.lastBlocksExtracted(), 1u);
    EXPECT_LT(incremental.lastBlocksExtracted(), blocks) << (project ? "projection on" : "projection off");
    // The far sphere's blocks hand over the very lists they held: no copy of unchanged points.
    int shared = 0, far_blocks = 0;
    for (const auto& b : incremental.lastBlocks().blocks) {
      if (b.points.front().x() < 0.5) continue;
      ++far_blocks;
      for (const auto& o : before.blocks) shared += o.block == b.block && o.points.sharesWith(b.points);
    }
    EXPECT_GT(far_blocks, 0);
    EXPECT_EQ(shared, far_blocks);
    incremental.extract(map);
    EXPECT_EQ(incremental.lastBlocksExtracted(), 0u);  // nothing changed since
    map.clear();
    integrateViews(map, integ, far_scene, far_scene.shapes[0].t, 2);
    expectSame();
    EXPECT_EQ(incremental.lastBlocksExtracted(), map.blockCount());
  }
}

// The update log names exactly the blocks updated since a reader's mark, for each of two
// readers with their own marks, and refuses (the reader then visits every block) once the map
// was cleared.
TEST(TsdfMap, TheUpdateLogNamesTheBlocksUpdatedSinceEachReadersMark) {
  AnalyticScene near_scene, far_scene;
  near_scene.shapes.push_back(sphere(0.04, Eigen::Vector3d(0, 0, 0.5)));
  far_scene.shapes.push_back(sphere(0.04, Eigen::Vector3d(1.0, 0, 0.5)));
  TsdfMap map;
  const TsdfIntegrator integ;
  integrateViews(map, integ, near_scene, near_scene.shapes[0].t, 2);
  const std::uint64_t first = map.markUpdates();
  integrateViews(map, integ, far_scene, far_scene.shapes[0].t, 2);
  const std::uint64_t second = map.markUpdates();
  integrateViews(map, integ, near_scene, near_scene.shapes[0].t, 1, 0.0, 5);
  auto updatedSince = [&](std::uint64_t mark, std::size_t* near, std::size_t* far) {
    *near = *far = 0;
    std::unordered_set<const TsdfBlock*> seen;
    const bool ok = map.forEachBlockUpdatedSince(mark, [&](const TsdfBlock& b) {
      EXPECT_TRUE(seen.insert(&b).second) << "a block named twice";
      (b.origin.x() * map.voxelSize() > 0.5 ? *far : *near) += 1;
    });
    return ok;
  };
  std::size_t near = 0, far = 0;
  ASSERT_TRUE(updatedSince(second, &near, &far));
  EXPECT_GT(near, 0u);
  EXPECT_EQ(far, 0u);  // the far sphere was not seen since the second mark
  ASSERT_TRUE(updatedSince(first, &near, &far));
  EXPECT_GT(near, 0u);
  EXPECT_GT(far, 0u);
  std::size_t total = 0;
  map.forEachBlock([&](const TsdfBlock& b) { total += b.revision > 0; });
  EXPECT_LE(near + far, total);
  map.clear();
  EXPECT_FALSE(updatedSince(second, &near, &far));
}

// A row scanned view by view: the pipeline that re-clusters only around the blocks each view
// changed finds what the one that clusters the whole surface every time finds (the same fruits,
// the same volumes), while it forms far fewer clusters late in the row. Both count a speck too
// small to fit.
TEST(TsdfMap, ClusteringOnlyAroundChangedBlocksFindsWhatAWholeUpdateFinds) {
  AnalyticScene scene;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Superellipsoid> truth;
  for (int i = 0; i < 14; ++i) {
    Superellipsoid s = sphere(0.025 + 0.015 * u(rng), Eigen::Vector3d(0.12 * i, 0.02 * u(rng), 0.45 + 0.1 * u(rng)));
    s.c *= 1.0 + 0.3 * u(rng);
    if (i % 5 == 3) s.t.x() = truth.back().t.x() + truth.back().a + s.a + 0.004;  // touching its neighbour
    truth.push_back(s);
    scene.shapes.push_back(s);
  }
  scene.shapes.push_back(sphere(0.008, Eigen::Vector3d(0.66, 0.0, 0.3)));  // below cluster_min_size
  TsdfMap map;
  const TsdfIntegrator integ;
  IncrementalSurfaceExtractor extractor;
  FruitShapePipeline local, whole;
  int local_clusters_late = 0, whole_clusters_late = 0, views = 0, local_updates = 0, local_specks = 0;
  for (double x = -0.1; x <= 0.12 * 14; x += 0.05, ++views) {
    for (const double side : {-1.0, 1.0}) {
      const PinholeCamera cam = PinholeCamera::lookingAt(Eigen::Vector3d(x, side * 0.35, 0.55),
                                                         Eigen::Vector3d(x + 0.05, 0.0, 0.5), 160, 120);
      ASSERT_TRUE(integrateFruitView(map, integ, scene, cam, 0.001, 100 + views).ok());
      const PointList surface = extractor.extract(map);
      const auto& a = local.update(extractor.lastBlocks());
      const auto& b = whole.update(surface);
      local_updates += local.lastStats().local;
      // Local clusters are whole components of the surface: never more left out than the whole has.
      EXPECT_LE(local.lastStats().left_out.undersized, whole.lastStats().left_out.undersized) << "view at x = " << x;
      if (local.lastStats().local) local_specks += local.lastStats().left_out.undersized;
      if (x > 1.0) {
        local_clusters_late += local.lastStats().clusters;
        whole_clusters_late += whole.lastStats().clusters;
      }
      std::vector<const FruitEstimate*> fa, fb;
      for (const auto& f : a) if (f.accepted) fa.push_back(&f);
      for (const auto& f : b) if (f.accepted) fb.push_back(&f);
      ASSERT_EQ(fa.size(), fb.size()) << "view at x = " << x;
      for (const FruitEstimate* f : fb) {
        const FruitEstimate* best = nullptr;
        for (const FruitEstimate* g : fa)
          if (!best || (g->center() - f->center()).norm() < (best->center() - f->center()).norm()) best = g;
        ASSERT_LT((best->center() - f->center()).norm(), 1e-3) << "view at x = " << x;
        EXPECT_NEAR(best->volume, f->volume, 0.01 * f->volume) << "view at x = " << x;
      }
    }
  }
  EXPECT_GT(local_updates, 2 * views - 2);  // all but the first
  // The speck is one of the clusters left out: the surface without it has one fewer, and its points.
  const PointList surface = extractor.extract(map);
  PointList without_speck;
  for (const Point& p : surface)
    if ((p - Eigen::Vector3d(0.66, 0.0, 0.3)).norm() > 0.02) without_speck.push_back(p);
  const int speck_points = static_cast<int>(surface.size() - without_speck.size());
  ASSERT_GT(speck_points, 0);
  FruitShapePipeline check;
  check.update(without_speck);
  EXPECT_EQ(whole.lastStats().left_out.undersized, check.lastStats().left_out.undersized + 1);
  EXPECT_EQ(whole.lastStats().left_out.undersized_points, check.lastStats().left_out.undersized_points + speck_points);
  EXPECT_GE(local_specks, 1);  // counted by a local update, where the views that saw it changed the surface
  int found = 0;
  for (const auto& f : whole.fruits()) found += f.accepted;
  EXPECT_GE(found, 12);
  EXPECT_LT(2 * local_clusters_late, whole_clusters_late);
}

// A component no fruit tracks (too large to fit: fruits and leaves grown into one) grows the
// local region one ring of blocks per pass; a long one is gathered whole after a few passes
// instead of costing a clustering per ring on every view, and is found whole either way.
TEST(FruitShapePipeline, ALongUntrackedComponentIsGatheredWholeAfterAFewPasses) {
  const double block = 0.064;
  std::map<std::tuple<std::int64_t, std::int64_t, std::int64_t>, PointList> by_block;
  int n = 0;
  for (double x = 0.0; x < 1.5; x += 0.003)  // a tube 1.5 m long, 3 cm across: 15 500 points
    for (int k = 0; k < 31; ++k, ++n) {
      const double a = 2.0 * M_PI * k / 31.0;
      const Eigen::Vector3d p(x, 0.3 + 0.015 * std::cos(a), 0.5 + 0.015 * std::sin(a));
      const GridCell c = cellOf(p, 1.0 / block);
      by_block[{c.x(), c.y(), c.z()}].push_back(p);
    }
  // Far from it, a row of other surface (blocks it never touches) that a local update leaves alone.
  for (double x = 0.0; x < 3.0; x += 0.2)
    for (int k = 0; k < 50; ++k) {
      const Eigen::Vector3d p(x + 0.001 * k, 1.0, 0.5 + 0.0005 * k);
      const GridCell c = cellOf(p, 1.0 / block);
      by_block[{c.x(), c.y(), c.z()}].push_back(p);
    }
  SurfaceBlocks blocks;
  blocks.block_size = block;
  for (auto& [key, pts] : by_block)
    blocks.blocks.push_back({GridCell(std::get<0>(key), std::get<1>(key), std::get<2>(key)), SharedPoints(pts)});
  blocks.all_changed = true;
  FruitShapePipeline pipeline;
  pipeline.update(blocks);
  ASSERT_EQ(pipeline.lastStats().left_out.oversized, 1) << n << " points";
  ASSERT_EQ(pipeline.lastStats().left_out.undersized, 15);  // the far row: 50-point specks
  // A view changes one block at the tube's end.
  blocks.all_changed = false;
  blocks.changed = {blocks.blocks.front().block};
  pipeline.update(blocks);
  EXPECT_TRUE(pipeline.lastStats().local);
  EXPECT_EQ(pipeline.lastStats().left_out.oversized, 1);  // found whole, not cut at the region's edge
  EXPECT_LE(pipeline.lastStats().cluster_passes, 5);       // 23 blocks long: a pass per ring would be 12 or more
  EXPECT_EQ(pipeline.lastStats().left_out.undersized, 0);  // the far row's specks were not gathered
}
