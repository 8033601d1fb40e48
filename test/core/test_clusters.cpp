#include <fruit_shape_completion/euclidean_clustering.h>
#include <fruit_shape_completion/fruit_center.h>
#include <fruit_shape_completion/neighbourhood_statistics.h>
#include <fruit_shape_completion/spatial_hash_grid.h>
#include <fruit_shape_completion/statistical_outlier_filter.h>
#include <fruit_shape_completion/surface_normals.h>
#include <fruit_shape_completion/synthetic_fruit.h>
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <limits>

using namespace fruit_shape_completion;

namespace {
Superellipsoid sphere(double r, const Eigen::Vector3d& c) { return Superellipsoid::sphere(r, c); }
PointList scan(const Superellipsoid& s, double seen = 1.0, unsigned seed = 1) {
  ScanParams p;
  p.visible_fraction = seen;
  p.seed = seed;
  return scanFruit(SyntheticFruit::fromSuperellipsoid(s), p);
}
}  // namespace

TEST(SpatialHashGrid, RadiusSearchMatchesBruteForce) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  PointList pts;
  for (int i = 0; i < 2000; ++i) pts.emplace_back(u(rng), u(rng), u(rng));
  pts.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0, 0);
  const SpatialHashGrid grid(pts, 0.02);
  std::vector<int> found;
  for (int q = 0; q < 50; ++q) {
    const Point p(u(rng), u(rng), u(rng));
    for (double radius : {0.01, 0.02, 0.035}) {
      grid.radiusSearch(p, radius, found);
      std::sort(found.begin(), found.end());
      std::vector<int> brute;
      for (int i = 0; i < static_cast<int>(pts.size()); ++i)
        if ((pts[i] - p).norm() <= radius) brute.push_back(i);
      EXPECT_EQ(found, brute);
      EXPECT_EQ(grid.anyWithin(p, radius), !brute.empty());
    }
  }
}

// forEachCell's promise (every point within the cell size of a cell's point lies in the
// ranges it hands over) and radius search, both against brute force.
void expectGridMatchesBruteForce(const SpatialHashGrid& grid, const PointList& pts, double cell) {
  std::size_t stored = 0;
  grid.forEachCell(0, grid.cells().size(), [&](const SpatialHashGrid::Cell& c, const std::pair<int, int>* ranges, int nr) {
    for (int j = c.begin; j < c.end; ++j) {
      ++stored;
      const Point& p = grid.storedPoint(j);
      EXPECT_EQ(pts[static_cast<std::size_t>(grid.originalIndex(j))], p);
      std::vector<int> in_ranges, brute;
      for (int r = 0; r < nr; ++r)
        for (int k = ranges[r].first; k < ranges[r].second; ++k)
          if ((grid.storedPoint(k) - p).norm() <= cell) in_ranges.push_back(grid.originalIndex(k));
      for (int i = 0; i < static_cast<int>(pts.size()); ++i)
        if (pts[static_cast<std::size_t>(i)].allFinite() && (pts[static_cast<std::size_t>(i)] - p).norm() <= cell)
          brute.push_back(i);
      std::sort(in_ranges.begin(), in_ranges.end());
      EXPECT_EQ(in_ranges, brute);
    }
  });
  std::size_t finite = 0;
  for (const Point& p : pts) finite += p.allFinite() ? 1 : 0;
  EXPECT_EQ(stored, finite);
  std::vector<int> found;
  for (std::size_t q = 0; q < pts.size(); q += 37) {
    if (!pts[q].allFinite()) continue;
    grid.radiusSearch(pts[q], cell, found);
    std::sort(found.begin(), found.end());
    std::vector<int> brute;
    for (int i = 0; i < static_cast<int>(pts.size()); ++i)
      if (pts[static_cast<std::size_t>(i)].allFinite() && (pts[static_cast<std::size_t>(i)] - pts[q]).norm() <= cell)
        brute.push_back(i);
    EXPECT_EQ(found, brute);
  }
}

TEST(SpatialHashGrid, RebuiltInPlaceOverWideCloudsMatchesBruteForce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  // Two clusters 700 m apart (a key of many bits: several radix passes, negative cells), far
  // and non-finite points. The same grid object is then rebuilt over a smaller cloud.
  PointList wide;
  for (int i = 0; i < 1500; ++i) wide.emplace_back(u(rng), u(rng), u(rng));
  for (int i = 0; i < 500; ++i) wide.emplace_back(-400.0 + u(rng), 300.0 + u(rng), -2.0 + u(rng));
  wide.emplace_back(1e13, 0.0, 0.0);
  wide.emplace_back(-1e300, 0.0, 0.0);
  wide.emplace_back(std::numeric_limits<double>::infinity(), 0.0, 0.0);
  SpatialHashGrid grid;
  grid.build(wide, 0.02);
  {
    SCOPED_TRACE("wide");
    expectGridMatchesBruteForce(grid, wide, 0.02);
  }
  PointList small(wide.begin(), wide.begin() + 700);
  grid.build(small, 0.01);
  {
    SCOPED_TRACE("rebuilt");
    expectGridMatchesBruteForce(grid, small, 0.01);
  }
  grid.build(PointList{Point(std::numeric_limits<double>::quiet_NaN(), 0, 0)}, 0.01);
  EXPECT_TRUE(grid.cells().empty());
  EXPECT_FALSE(grid.anyWithin(Point::Zero(), 1.0));
}

// The integrator's one-pass neighbourhood statistics against a brute-force double computation:
// the k-NN mean of every point (with exact duplicates, sparse stray points and a NaN), the
// outlier flags that follow from it, and the normals against an eigen-decomposition of each
// point's own neighbourhood.
TEST(NeighbourhoodStatistics, MatchBruteForceOnANoisySphereWithStrays) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.001);
  std::uniform_real_distribution<double> u(-0.08, 0.08);
  PointList pts;
  for (const Point& d : fibonacciSphere(3000)) pts.push_back(0.04 * d + Point(noise(rng), noise(rng), noise(rng)));
  for (int i = 0; i < 40; ++i) pts.push_back(pts[static_cast<std::size_t>(i * 53)]);  // exact duplicates
  for (int i = 0; i < 60; ++i) pts.emplace_back(u(rng), u(rng), 0.06 + std::abs(u(rng)));  // strays
  pts.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0);

  // A sphere point has ~16 neighbours at 6 mm and ~45 at 1 cm (the rank count), ~105 at 1.5 cm
  // and ~190 at 2 cm (over its limit: the extraction, from either end with k 60 and 10).
  const std::pair<double, int> cases[] = {{0.01, 10}, {0.006, 10}, {0.02, 10}, {0.015, 60}};
  for (const auto& [radius, k] : cases) {
    SCOPED_TRACE(testing::Message() << "radius " << radius << " k " << k);
    NeighbourhoodQuery q;  // normals
    q.radius = radius;
    q.k = k;
    std::vector<double> knn;
    std::vector<Eigen::Vector3d> normals;
    analyseNeighbourhoods(pts, q, &knn, &normals);
    ASSERT_EQ(knn.size(), pts.size());
    ASSERT_EQ(normals.size(), pts.size());

    int sparse = 0, compared = 0, close_normals = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (!pts[i].allFinite()) {
        EXPECT_TRUE(std::isnan(knn[i]));  // as the stand-alone filter: no statistic, flagged
        EXPECT_FALSE(normals[i].allFinite());
        continue;
      }
      std::vector<double> d2;
      PointList hood;
      for (std::size_t j = 0; j < pts.size(); ++j) {
        const double dd = (pts[j] - pts[i]).squaredNorm();
        if (pts[j].allFinite() && dd <= q.radius * q.radius) {
          hood.push_back(pts[j]);
          if (j != i) d2.push_back(dd);
        }
      }
      EXPECT_NEAR(knn[i], meanKnnDistance(d2, q.k, q.radius), 1e-7) << i;
      if (hood.size() < 5) {
        ++sparse;
        EXPECT_FALSE(normals[i].allFinite()) << i;
        continue;
      }
      if (!normals[i].allFinite()) continue;
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (const Point& h : hood) mean += h;
      mean /= static_cast<double>(hood.size());
      Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
      for (const Point& h : hood) cov += (h - mean) * (h - mean).transpose();
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
      EXPECT_NEAR(normals[i].norm(), 1.0, 1e-9);
      ++compared;
      if (std::abs(normals[i].dot(es.eigenvectors().col(0))) > std::cos(2.0 * M_PI / 180.0)) ++close_normals;
    }
    EXPECT_GT(sparse, 30);      // most strays have under 5 neighbours: no normal, k-NN mean = radius
    EXPECT_GT(compared, 2900);  // the sphere's points all got a normal
    EXPECT_GT(close_normals, 0.99 * compared);

    // The outlier flags equal those of the stand-alone filter (its own neighbour search).
    const std::vector<char> flags = flagStatisticalOutliers(knn, 2.0);
    OutlierFilterParams of;
    of.search_radius = radius;
    of.k = k;
    EXPECT_EQ(flags, findStatisticalOutliers(pts, of));
    int stray_flags = 0;
    for (std::size_t i = 3040; i + 1 < pts.size(); ++i) stray_flags += flags[i];
    EXPECT_GT(stray_flags, 30);

    // Two threads split the cells and give the same values.
    q.threads = 2;
    std::vector<double> knn2;
    std::vector<Eigen::Vector3d> normals2;
    analyseNeighbourhoods(pts, q, &knn2, &normals2);
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (!std::isnan(knn[i])) EXPECT_EQ(knn[i], knn2[i]) << i;
      if (normals[i].allFinite()) EXPECT_EQ(normals[i], normals2[i]) << i;
    }
  }
}

TEST(EuclideanClustering, TwoFruitsTwoCentimetresApartStayTwo) {
  // Surfaces 2 cm apart (as a TSDF surface would deliver them) are two clusters at 1 cm.
  PointList cloud = scan(sphere(0.04, Eigen::Vector3d(0, 0, 0)));
  const PointList other = scan(sphere(0.035, Eigen::Vector3d(0.095, 0, 0)), 1.0, 2);
  cloud.insert(cloud.end(), other.begin(), other.end());
  const auto clusters = euclideanClusters(cloud, ClusteringParams());
  ASSERT_EQ(clusters.size(), 2u);
  EXPECT_EQ(clusters[0].size() + clusters[1].size(), cloud.size());
  // Touching fruits merge: clustering alone cannot split them.
  PointList touching = scan(sphere(0.04, Eigen::Vector3d(0, 0, 0)));
  const PointList near = scan(sphere(0.04, Eigen::Vector3d(0.083, 0, 0)), 1.0, 3);
  touching.insert(touching.end(), near.begin(), near.end());
  EXPECT_EQ(euclideanClusters(touching, ClusteringParams()).size(), 1u);
}

TEST(EuclideanClustering, SizeLimitsAndNonFinitePoints) {
  PointList cloud = scan(sphere(0.04, Eigen::Vector3d(0, 0, 0)));
  const size_t fruit_points = cloud.size();
  // A small blob of 20 points far away is below min_size.
  for (int i = 0; i < 20; ++i) cloud.emplace_back(1.0 + 0.002 * i, 0, 0);
  cloud.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0, 0);
  cloud.emplace_back(0, std::numeric_limits<double>::infinity(), 0);
  ClusteringParams params;
  auto clusters = euclideanClusters(cloud, params);
  ASSERT_EQ(clusters.size(), 1u);
  EXPECT_EQ(clusters[0].size(), fruit_points);
  params.max_size = static_cast<int>(fruit_points) - 1;
  EXPECT_TRUE(euclideanClusters(cloud, params).empty());
  EXPECT_TRUE(euclideanClusters({}, ClusteringParams()).empty());
}

TEST(SurfaceNormals, SphereNormalsPointToTheCentre) {
  const Eigen::Vector3d c(0.2, 0.3, 0.4);
  const PointList pts = scan(sphere(0.04, c), 0.5);
  NormalParams params;
  params.max_points = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : pts) mean += p / pts.size();
  const SurfaceNormals n = estimateNormals(pts, params, mean);
  ASSERT_EQ(n.normals.size(), pts.size());
  EXPECT_GT(n.valid, static_cast<int>(0.9 * pts.size()));
  int good = 0;
  for (size_t i = 0; i < pts.size(); ++i)
    if (n.normals[i].allFinite() && n.normals[i].dot((c - pts[i]).normalized()) > std::cos(0.2)) ++good;
  EXPECT_GT(good, 0.9 * n.valid);
}

TEST(SurfaceNormals, DegenerateNeighbourhoodsAreDroppedOneByOne) {
  PointList pts = scan(sphere(0.04, Eigen::Vector3d::Zero()), 0.5);
  const size_t n_good = pts.size();
  pts.emplace_back(1, 1, 1);  // isolated: too few neighbours
  for (int i = 0; i < 10; ++i) pts.emplace_back(2 + 0.001 * i, 0, 0);  // a line
  pts.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0, 0);
  NormalParams params;
  params.max_points = 0;
  const SurfaceNormals n = estimateNormals(pts, params, Eigen::Vector3d::Zero());
  for (size_t i = n_good; i < pts.size(); ++i) EXPECT_FALSE(n.normals[i].allFinite()) << i;
  EXPECT_GT(n.valid, static_cast<int>(0.9 * n_good));
  const Eigen::Vector3d w = estimateFruitCenter(pts, n.normals, 2.5);
  EXPECT_LT(w.norm(), 0.004);  // the bad points did not spoil the centre
}

TEST(FruitCenter, HalfSeenSphereCentreFromNormalLines) {
  const Eigen::Vector3d c(0.5, -0.2, 0.8);
  const PointList pts = scan(sphere(0.045, c), 0.5, 9);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : pts) mean += p / pts.size();
  const SurfaceNormals n = estimateNormals(pts, NormalParams(), mean);
  const Eigen::Vector3d w = estimateFruitCenter(pts, n.normals, 2.5);
  EXPECT_LT((w - c).norm(), 0.003);
  EXPECT_GT((mean - c).norm(), 0.015);  // the mean alone would be far off
  EXPECT_TRUE(checkClusterShape(pts, n.normals).ok);
}

TEST(FruitCenter, PlanarAndCollinearClustersAreRejectedWithAReason) {
  PointList plane, line;
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 30; ++j) plane.emplace_back(0.003 * i, 0.003 * j, 0.0);
  for (int i = 0; i < 200; ++i) line.emplace_back(0.001 * i, 0.0, 0.0);
  const SurfaceNormals np = estimateNormals(plane, NormalParams(), Eigen::Vector3d(0, 0, 1));
  const ClusterShapeCheck cp = checkClusterShape(plane, np.normals);
  EXPECT_FALSE(cp.ok);
  EXPECT_NE(cp.reason.find("planar"), std::string::npos) << cp.reason;
  // The centre stays finite (pulled to the mean) even with parallel normals.
  EXPECT_TRUE(estimateFruitCenter(plane, np.normals, 2.5).allFinite());
  const SurfaceNormals nl = estimateNormals(line, NormalParams(), Eigen::Vector3d(0, 0, 1));
  const ClusterShapeCheck cl = checkClusterShape(line, nl.normals);
  EXPECT_FALSE(cl.ok);
  EXPECT_NE(cl.reason.find("collinear"), std::string::npos) << cl.reason;
}
