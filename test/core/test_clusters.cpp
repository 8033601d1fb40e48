#include <fruit_shape_completion/euclidean_clustering.h>
#include <fruit_shape_completion/fruit_center.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/statistical_outlier_filter.h>
#include <fruit_shape_completion/surface_normals.h>
#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>

using namespace fruit_shape_completion;

namespace {
Superellipsoid sphere(double r, const Eigen::Vector3d& c) { return Superellipsoid::sphere(r, c); }
PointList scan(const Superellipsoid& s, double seen = 1.0, unsigned seed = 1) {
  ScanParams p;
  p.visible_fraction = seen;
  p.seed = seed;
  return scanFruit(SyntheticFruit::fromSuperellipsoid(s), p);
}

// The outlier statistic's definition, by brute force over the finite points: a point's mean
// distance to its k nearest (within search_radius; fewer there: the radius), flagged beyond the
// mean by std_mul sample deviations.
std::vector<char> outliersByDefinition(const PointList& pts, const OutlierFilterParams& params) {
  std::vector<std::size_t> finite;
  for (std::size_t i = 0; i < pts.size(); ++i)
    if (pts[i].allFinite()) finite.push_back(i);
  std::vector<double> mean_knn(pts.size(), 0.0);
  const auto k = static_cast<std::size_t>(params.k);
  for (std::size_t i : finite) {
    std::vector<double> d;
    for (std::size_t j : finite)
      if (j != i) d.push_back((pts[j] - pts[i]).norm());
    const bool enough = d.size() >= k;
    if (enough) std::nth_element(d.begin(), d.begin() + static_cast<long>(k - 1), d.end());
    if (enough) std::sort(d.begin(), d.begin() + static_cast<long>(k));
    mean_knn[i] = enough && d[k - 1] <= params.search_radius
                      ? std::accumulate(d.begin(), d.begin() + static_cast<long>(k), 0.0) / params.k
                      : params.search_radius;
  }
  double mean = 0.0, var = 0.0;
  for (std::size_t i : finite) mean += mean_knn[i] / static_cast<double>(finite.size());
  for (std::size_t i : finite) var += (mean_knn[i] - mean) * (mean_knn[i] - mean) / static_cast<double>(finite.size() - 1);
  const double threshold = mean + params.std_mul * std::sqrt(var);
  std::vector<char> flags(pts.size(), 1);
  for (std::size_t i : finite) flags[i] = mean_knn[i] > threshold;
  return flags;
}
}  // namespace

TEST(StatisticalOutlierFilter, FlagsStraysAsTheDefinitionSays) {
  // A noisy sphere with strays around it: a point is an outlier when its mean distance to its
  // k nearest neighbours (within search_radius, else that radius) exceeds the mean of that value
  // by std_mul standard deviations (the sample deviation, as PCL).
  PointList pts = scan(sphere(0.04, Eigen::Vector3d(0.3, 0.1, 0.5)));
  const std::size_t on_sphere = pts.size();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.12, 0.12);
  while (pts.size() < on_sphere + 40) {
    const Eigen::Vector3d p = Eigen::Vector3d(0.3, 0.1, 0.5) + Eigen::Vector3d{u(rng), u(rng), u(rng)};
    if (std::abs((p - Eigen::Vector3d(0.3, 0.1, 0.5)).norm() - 0.04) > 0.03) pts.push_back(p);
  }
  pts.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0, 0);
  OutlierFilterParams params;
  const std::vector<char> flags = findStatisticalOutliers(pts, params);
  ASSERT_EQ(flags.size(), pts.size());
  EXPECT_TRUE(flags.back());  // the NaN point
  const std::size_t n = pts.size() - 1;
  const std::vector<char> expected = outliersByDefinition(pts, params);
  std::size_t agree = 0, strays = 0, sphere_flags = 0;
  for (std::size_t i = 0; i < n; ++i) {
    agree += expected[i] == flags[i];
    (i < on_sphere ? sphere_flags : strays) += flags[i];
  }
  EXPECT_GE(agree, n - 1);  // rounding may tip a point at the threshold
  EXPECT_GT(strays, 30u);
  EXPECT_LT(sphere_flags, on_sphere / 50);
  params.k = 0;
  EXPECT_THROW(params.validate(), std::invalid_argument);
  params.k = 1001;  // k distances kept per point: bounded
  EXPECT_THROW(params.validate(), std::invalid_argument);
  params.k = 10;
  params.search_radius = 0.06;  // pairs grow with the radius squared, on every view: bounded
  EXPECT_THROW(params.validate(), std::invalid_argument);
  params.search_radius = 0.05;
  EXPECT_NO_THROW(params.validate());
}

TEST(StatisticalOutlierFilter, RepeatedPointsCountAsTheirOwnNearestNeighbours) {
  // A driver repeating a point (or writing pixels without depth as the origin) piles thousands of
  // copies into one cell: they are merged before the search, and the flags stay the definition's.
  PointList pts = scan(sphere(0.04, Eigen::Vector3d(0.3, 0.1, 0.5)));
  const std::size_t on_sphere = pts.size();
  pts.insert(pts.end(), 3000, pts[7]);                        // copies of a surface point
  pts.insert(pts.end(), 2500, Eigen::Vector3d(0.0, 0.0, 0.0));  // the origin, far from the fruit
  pts.emplace_back(0.3, 0.1, 0.62);                           // one stray 8 cm off the surface
  pts.insert(pts.end(), 3, Eigen::Vector3d(0.42, 0.1, 0.5));  // three copies of another: fewer than k
  OutlierFilterParams params;
  const std::vector<char> flags = findStatisticalOutliers(pts, params);
  const std::vector<char> expected = outliersByDefinition(pts, params);
  ASSERT_EQ(flags.size(), pts.size());
  std::size_t agree = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) agree += flags[i] == expected[i];
  EXPECT_GE(agree, pts.size() - 1);  // rounding may tip a point at the threshold
  EXPECT_TRUE(flags[on_sphere + 5500]);  // the lone stray
  EXPECT_TRUE(flags.back());             // a point with only two copies near it is still a stray
  EXPECT_FALSE(flags[on_sphere + 4000]);  // a pile of copies is dense, as PCL would count it
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
  ClustersLeftOut left_out{-1, -1, -1};  // every count is set anew
  auto clusters = euclideanClusters(cloud, params, &left_out);
  ASSERT_EQ(clusters.size(), 1u);
  EXPECT_EQ(clusters[0].size(), fruit_points);
  EXPECT_EQ(left_out.oversized, 0);  // the small blob is below min_size, not counted as too large
  EXPECT_EQ(left_out.undersized, 1);
  EXPECT_EQ(left_out.undersized_points, 20);
  params.max_size = static_cast<int>(fruit_points) - 1;
  EXPECT_TRUE(euclideanClusters(cloud, params, &left_out).empty());
  EXPECT_EQ(left_out.oversized, 1);
  EXPECT_EQ(left_out.undersized, 1);
  EXPECT_EQ(left_out.undersized_points, 20);
  // Nothing to cluster: nothing left out, whatever the struct held.
  EXPECT_TRUE(euclideanClusters({}, params, &left_out).empty());
  EXPECT_EQ(left_out.oversized + left_out.undersized + left_out.undersized_points, 0);
  // The pipeline counts both in its stats (and fits nothing).
  PipelineParams pipeline_params;
  pipeline_params.clustering = params;
  FruitShapePipeline pipeline(pipeline_params);
  EXPECT_TRUE(pipeline.update(cloud).empty());
  EXPECT_EQ(pipeline.lastStats().left_out.oversized, 1);
  EXPECT_EQ(pipeline.lastStats().left_out.undersized, 1);
  EXPECT_EQ(pipeline.lastStats().left_out.undersized_points, 20);
  EXPECT_EQ(pipeline.lastStats().clusters, 0);
  EXPECT_TRUE(euclideanClusters({}, ClusteringParams()).empty());
}

// Piles of duplicates (a stuck sensor, a replayed frame) cluster like single points, and two
// piles farther apart than the tolerance stay two, as do chains that bridge them only through
// points of their own.
TEST(EuclideanClustering, DuplicatePilesAreClusteredAsTheirPositions) {
  PointList pts(60000, Eigen::Vector3d(0.1, 0.2, 0.3));
  pts.insert(pts.end(), 40000, Eigen::Vector3d(0.1, 0.2, 0.315));  // 1.5 cm away: another cluster
  ClusteringParams params;
  params.min_size = 1;
  params.max_size = 1000000;
  auto clusters = euclideanClusters(pts, params);
  ASSERT_EQ(clusters.size(), 2u);
  EXPECT_EQ(clusters[0].size(), 60000u);
  EXPECT_EQ(clusters[1].size(), 40000u);
  EXPECT_EQ(clusters[1].front(), 60000);
  // A point midway links them (0.75 cm to each).
  pts.emplace_back(0.1, 0.2, 0.3075);
  clusters = euclideanClusters(pts, params);
  ASSERT_EQ(clusters.size(), 1u);
  EXPECT_EQ(clusters[0].size(), pts.size());
  // Two piles whose cells' packed keys coincide (2^21 cells of tolerance / 8 apart, 2.62144 km
  // at 1 cm) are two clusters, not one.
  PointList far(3, Eigen::Vector3d(0.0005, 0.0005, 0.0005));
  far.insert(far.end(), 3, Eigen::Vector3d(0.0005 + 2621.44, 0.0005, 0.0005));
  clusters = euclideanClusters(far, params);
  ASSERT_EQ(clusters.size(), 2u);
  EXPECT_EQ(clusters[0].size(), 3u);
  EXPECT_EQ(clusters[1].size(), 3u);
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

TEST(FruitCenter, TheSphereThroughASmallCapFindsItsCentre) {
  const Eigen::Vector3d c(0.2, 0.4, 0.9);
  ScanParams p;
  p.visible_fraction = 0.2;
  p.voxel = 0.0;
  p.noise_sigma = 0.0;
  p.view_dir = Eigen::Vector3d(1, -2, 0.5);
  PointList cap = scanFruit(SyntheticFruit::fromSuperellipsoid(sphere(0.035, c)), p);
  cap.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0);  // skipped, not spoiling
  const SphereFit fit = fitSphere(cap);
  ASSERT_TRUE(fit.valid());
  EXPECT_LT((fit.center - c).norm(), 1e-6);
  EXPECT_NEAR(fit.radius, 0.035, 1e-6);
  // A flat patch (noisy too) or a line pins no sphere down; nor do three points.
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.0005);
  PointList plane, line;
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 30; ++j) plane.emplace_back(0.003 * i, 0.003 * j, noise(rng));
  for (int i = 0; i < 200; ++i) line.emplace_back(0.001 * i, noise(rng), noise(rng));
  EXPECT_FALSE(fitSphere(plane).valid());
  EXPECT_FALSE(fitSphere(line).valid());
  EXPECT_FALSE(fitSphere(PointList(cap.begin(), cap.begin() + 3)).valid());
  EXPECT_FALSE(fitSphere({}).valid());
}

TEST(FruitCenter, TheNormalLinesHoldLessOverASmallerCap) {
  // The mean squared sine of the normals' angle to the weakest direction, for a sphere seen over
  // a cap of half angle t (share s = (1 - cos t) / 2): below a hemisphere (2 - c - c^2) / 3 with
  // c = cos t (a quarter: 5/12; 1/2 at c = (sqrt(3) - 1) / 2, 32 % seen), beyond it
  // (4 + c + c^2) / 6 (2/3 at a hemisphere and all round, 0.625 at three quarters).
  const Eigen::Vector3d c(0.0, 0.0, 1.0);
  const double share_at_half = 0.5 * (1.0 - 0.5 * (std::sqrt(3.0) - 1.0));
  for (const auto& [seen, expected] : {std::pair{1.0, 2.0 / 3.0}, {0.75, 0.625}, {0.5, 2.0 / 3.0},
                                       {share_at_half, 0.5}, {0.25, 5.0 / 12.0}}) {
    ScanParams p;
    p.visible_fraction = seen;
    p.voxel = 0.0;
    p.noise_sigma = 0.0;
    const PointList pts = scanFruit(SyntheticFruit::fromSuperellipsoid(sphere(0.04, c)), p);
    std::vector<Eigen::Vector3d> normals;
    for (const auto& q : pts) normals.push_back((c - q).normalized());
    EXPECT_NEAR(normalLineHold(pts, normals), expected, 0.01) << "seen " << seen;
  }
  EXPECT_EQ(normalLineHold({}, {}), 0.0);
  EXPECT_EQ(normalLineHold({c}, {Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN())}), 0.0);
}

TEST(FruitCenter, AFlattenedFruitSeenAllRoundKeepsItsCentre) {
  // A flattened fruit's normals hold the centre less at any share (under 0.5 for these 7:4 and
  // 2:1 oblate bodies seen all round), so a small one takes the sphere's centre even seen all
  // round: for a body symmetric about its centre that is the centre too. A large one keeps the
  // normal lines.
  for (const auto& [a, c] : {std::pair{0.035, 0.02}, {0.06, 0.03}}) {
    Superellipsoid flat = Superellipsoid::sphere(a, Eigen::Vector3d(0.1, 0.2, 0.6));
    flat.c = c;
    const PointList pts = scanFruit(SyntheticFruit::fromSuperellipsoid(flat), ScanParams());
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& q : pts) mean += q / pts.size();
    const SurfaceNormals n = estimateNormals(pts, NormalParams(), mean);
    EXPECT_LT(normalLineHold(pts, n.normals), 0.5) << "a " << a;
    const Eigen::Vector3d w = blendedFruitCenter(pts, n.normals, 2.5);
    EXPECT_LT((w - flat.t).norm(), 0.002) << "a " << a;
    const bool large = fitSphere(pts).radius > CenterPriorBlend().sphere_radius_none;
    EXPECT_EQ(large, a > 0.05) << "a " << a << ": sphere radius " << fitSphere(pts).radius;
    if (large) EXPECT_EQ(w, estimateFruitCenter(pts, n.normals, 2.5));
    else EXPECT_NE(w, estimateFruitCenter(pts, n.normals, 2.5));
  }
}

TEST(FruitCenter, APriorBehindTheDeepestSeenPointsMovesForwardToThem) {
  // A sphere seen from +x over a hemisphere (its outline through the centre): the normals face
  // -x on average and the seen points reach back to the centre's depth, so a prior 15 mm
  // deeper moves forward (+x) to the deepest points' 99th percentile plus the margin.
  const Eigen::Vector3d c(0.3, -0.1, 0.7);
  const double r = 0.04, margin = 0.003;
  ScanParams p;
  p.visible_fraction = 0.5;
  p.voxel = 0.0;
  p.noise_sigma = 0.0;
  PointList pts = scanFruit(SyntheticFruit::fromSuperellipsoid(sphere(r, c)), p);
  std::vector<Eigen::Vector3d> normals;
  for (const auto& q : pts) normals.push_back((c - q).normalized());
  pts.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0);  // skipped
  normals.emplace_back(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0);
  std::vector<double> seen_depth;  // how far each point lies behind the front, along -x
  for (const auto& q : pts)
    if (q.allFinite()) seen_depth.push_back(c.x() + r - q.x());
  std::sort(seen_depth.begin(), seen_depth.end());
  const double deepest = seen_depth[static_cast<std::size_t>(0.99 * (seen_depth.size() - 1))];
  ASSERT_NEAR(deepest, r, 0.002);  // the outline: the centre's depth

  const Eigen::Vector3d deep = c - Eigen::Vector3d(0.015, 0.0, 0.0);
  const Eigen::Vector3d moved = limitToSeenDepth(pts, normals, deep, margin);
  EXPECT_NEAR(c.x() + r - moved.x(), deepest + margin, 2e-4);  // at the limit, along the view
  EXPECT_NEAR(moved.y(), deep.y(), 2e-4);
  EXPECT_NEAR(moved.z(), deep.z(), 2e-4);
  // In front of the limit, or with a negative margin: untouched.
  EXPECT_EQ(limitToSeenDepth(pts, normals, c, margin), c);
  EXPECT_EQ(limitToSeenDepth(pts, normals, deep, -1.0), deep);
  // A prior 35 mm off the centre of a sphere seen all round: its deepest points lie on its far
  // side, whichever way the (nearly cancelling) normals face on average.
  const Eigen::Vector3d deeper = c - Eigen::Vector3d(0.035, 0.0, 0.0);
  p.visible_fraction = 1.0;
  const PointList all = scanFruit(SyntheticFruit::fromSuperellipsoid(sphere(r, c)), p);
  std::vector<Eigen::Vector3d> all_normals;
  for (const auto& q : all) all_normals.push_back((c - q).normalized());
  EXPECT_EQ(limitToSeenDepth(all, all_normals, deeper, margin), deeper);
  // Fewer than ten normals say nothing about the side it was seen from.
  EXPECT_EQ(limitToSeenDepth(PointList(pts.begin(), pts.begin() + 9),
                             std::vector<Eigen::Vector3d>(normals.begin(), normals.begin() + 9), deep, margin),
            deep);
  // blendedFruitCenter holds its prior to the seen depth only where the normal lines scatter.
  // Exact normals of a sphere seen over a quarter meet at its centre, 18 mm behind the deepest
  // seen points, and keep the prior there; tilted by about 7 degrees each they scatter (as
  // lobes and noise make them) and the prior is held to those points plus the margin.
  p.visible_fraction = 0.25;
  const PointList cap = scanFruit(SyntheticFruit::fromSuperellipsoid(sphere(r, c)), p);
  std::vector<Eigen::Vector3d> exact, tilted;
  std::mt19937 rng(11);
  std::normal_distribution<double> tilt(0.0, 0.09);
  double cap_deepest = 0.0;
  for (const auto& q : cap) {
    exact.push_back((c - q).normalized());
    tilted.push_back((exact.back() + Eigen::Vector3d(tilt(rng), tilt(rng), tilt(rng))).normalized());
    cap_deepest = std::max(cap_deepest, c.x() + r - q.x());
  }
  ASSERT_NEAR(cap_deepest, r / 2, 0.002);  // a quarter of a sphere's surface reaches half way
  CenterPriorBlend limited;
  limited.rim_margin = margin;
  EXPECT_LT((blendedFruitCenter(cap, exact, 2.5, limited) - c).norm(), 5e-4);
  const Eigen::Vector3d held = blendedFruitCenter(cap, tilted, 2.5, limited);
  EXPECT_NEAR(c.x() + r - held.x(), cap_deepest + margin, 5e-4);
  CenterPriorBlend no_limit;
  no_limit.rim_margin = -1.0;
  EXPECT_GT(c.x() + r - blendedFruitCenter(cap, tilted, 2.5, no_limit).x(), cap_deepest + margin + 0.01);
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
