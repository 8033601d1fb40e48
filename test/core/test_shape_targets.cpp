// Which predicted surface becomes the planner's targets (shape_targets.h): settled fruits hand
// over nothing, a cap spreads each fruit's targets, targets sit `offset` outside the surface
// along its outward normal and carry that normal as the side to view them from. And the 90 %
// volume interval and centre radius, which come from the same seen share (volume_interval.h,
// center_uncertainty.h).
#include <fruit_shape_completion/center_uncertainty.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>
#include <fruit_shape_completion/missing_surface.h>
#include <fruit_shape_completion/shape_targets.h>
#include <fruit_shape_completion/volume_interval.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

using namespace fruit_shape_completion;

namespace {

// A fitted fruit seen on the side z > z_seen only (its observed points are surface samples there).
FruitEstimate halfSeen(const Superellipsoid& shape, double z_seen, int samples = 300) {
  FruitEstimate f;
  f.shape = shape;
  f.accepted = true;
  PointList seen;
  for (const auto& p : shape.sampleSurface(2000))
    if (p.z() - shape.t.z() > z_seen) seen.push_back(p);
  f.points = seen;
  MissingSurfaceParams m;
  m.samples = samples;
  f.missing_surface = predictMissingSurface(shape, f.points, m);
  return f;
}

}  // namespace

TEST(ShapeTargets, SettledFruitsHandOverNothingAndTheCapSpreadsTheRest) {
  const Superellipsoid a = Superellipsoid::sphere(0.04, Eigen::Vector3d(0, 0, 0.5));
  const Superellipsoid b = Superellipsoid::sphere(0.03, Eigen::Vector3d(0.3, 0, 0.5));
  const FruitEstimate mostly = halfSeen(a, -0.025);  // seen down to 2.5 cm below the centre
  const FruitEstimate half = halfSeen(b, 0.0);
  // Samples within the missing-surface threshold (1.5 cm) of a seen point count as seen.
  const double c_mostly = seenCoverage(mostly, 300), c_half = seenCoverage(half, 300);
  EXPECT_GT(c_mostly, 0.85);
  EXPECT_GT(c_half, 0.5);
  EXPECT_LT(c_half, 0.8);
  ASSERT_GE(mostly.missing_surface.size(), 10u);

  ShapeTargetParams p;  // every accepted fruit, all its unseen samples
  p.offset = 0.0;         // on the surface: the spread below is the samples'
  const ShapeTargets all = selectShapeTargets({mostly, half}, 300, p);
  EXPECT_EQ(all.points.size(), mostly.missing_surface.size() + half.missing_surface.size());
  ASSERT_EQ(all.directions.size(), all.points.size());

  p.settled_coverage = 0.85;
  const ShapeTargets unsettled = selectShapeTargets({mostly, half}, 300, p);
  EXPECT_EQ(unsettled.points.size(), half.missing_surface.size());

  p.settled_coverage = 1.0;
  p.per_fruit = 10;
  const ShapeTargets capped = selectShapeTargets({mostly, half}, 300, p);
  ASSERT_EQ(capped.points.size(), 20u);
  // The ten of the half-seen fruit spread over its unseen lower half: from near its equator to
  // near its bottom.
  double lowest = 1, highest = -1;
  for (std::size_t i = 10; i < 20; ++i) {
    lowest = std::min(lowest, capped.points[i].z() - 0.5);
    highest = std::max(highest, capped.points[i].z() - 0.5);
  }
  EXPECT_LT(lowest, -0.025);
  EXPECT_GT(highest, -0.015);

  FruitEstimate rejected = half;
  rejected.accepted = false;
  EXPECT_TRUE(selectShapeTargets({rejected}, 300, ShapeTargetParams()).points.empty());
}

TEST(ShapeTargets, TargetsSitOutsideAlongTheOutwardNormalWhichTheyCarry) {
  Superellipsoid s;
  s.a = 0.05, s.b = 0.03, s.c = 0.04, s.e1 = 0.4, s.e2 = 0.7;
  s.t = Eigen::Vector3d(0.1, -0.2, 0.6);
  s.rpy = Eigen::Vector3d(0.3, -0.2, 1.0);
  const FruitEstimate f = halfSeen(s, 0.0);
  ASSERT_GT(f.missing_surface.size(), 50u);
  ShapeTargetParams p;
  p.offset = 0.02;
  const ShapeTargets t = selectShapeTargets({f}, 300, p);
  ASSERT_EQ(t.points.size(), f.missing_surface.size());
  for (std::size_t i = 0; i < t.points.size(); ++i) {
    const Eigen::Vector3d& n = t.directions[i];
    EXPECT_NEAR(n.norm(), 1.0, 1e-9);
    // Outside the surface, 2 cm from its sample, along a direction that leaves the fruit.
    EXPECT_NEAR((t.points[i] - f.missing_surface[i]).norm(), 0.02, 1e-9);
    EXPECT_GT(s.implicit(t.points[i]), 1.0);
    EXPECT_LT(s.implicit(f.missing_surface[i] - 0.005 * n), 1.0);
  }
  p.view_side = false;
  for (const auto& d : selectShapeTargets({f}, 300, p).directions) EXPECT_EQ(d, Eigen::Vector3d::Zero());
}

TEST(ShapeTargets, BadParametersAreRefusedByName) {
  ShapeTargetParams p;
  p.settled_coverage = 1.5;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p = ShapeTargetParams();
  p.per_fruit = -1;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p = ShapeTargetParams();
  p.offset = std::nan("");
  try {
    p.validate();
    FAIL() << "a NaN offset was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("target_offset"), std::string::npos);
  }
  for (auto bad : {+[](ShapeTargetParams& q) { q.view_gain = -1.0; }, +[](ShapeTargetParams& q) { q.view_fov_deg = 180.0; },
                   +[](ShapeTargetParams& q) { q.view_max_range = 0.0; }}) {
    p = ShapeTargetParams();
    bad(p);
    EXPECT_THROW(p.validate(), std::invalid_argument);
  }
}

TEST(VolumeInterval, NarrowsAsMoreOfTheFruitIsSeenAndWidensWithTheResidual) {
  const double v = 2e-4;
  for (double rms : {0.002, 0.004, 0.007}) {
    double last_width = 1e9;
    for (double seen : {0.0, 0.3, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.0}) {
      const VolumeInterval ci = volumeInterval90(v, seen, rms);
      EXPECT_LT(ci.lo, v) << seen;
      EXPECT_GT(ci.hi, v) << seen;
      EXPECT_LE(ci.hi - ci.lo, last_width + 1e-15) << "wider at " << seen;
      last_width = ci.hi - ci.lo;
    }
  }
  for (double seen : {0.3, 0.6, 0.8, 0.95, 1.0}) {
    const VolumeInterval tight = volumeInterval90(v, seen, 0.002), mid = volumeInterval90(v, seen, 0.004),
                         loose = volumeInterval90(v, seen, 0.007);
    EXPECT_LE(tight.hi - tight.lo, mid.hi - mid.lo + 1e-15) << seen;
    EXPECT_LE(mid.hi - mid.lo, loose.hi - loose.lo + 1e-15) << seen;
  }
  // The calibration's figures: seen all round with a close fit, about +-8 %; half seen, about +-31 %.
  EXPECT_NEAR(volumeInterval90(v, 1.0, 0.002).lo, 0.91 * v, 1e-12);
  EXPECT_NEAR(volumeInterval90(v, 1.0, 0.002).hi, 1.07 * v, 1e-12);
  const VolumeInterval half = volumeInterval90(v, 0.5, 0.002);
  EXPECT_NEAR(0.5 * (half.hi - half.lo) / v, 0.31, 0.02);
  // Nonsense in, the widest interval out.
  const VolumeInterval bad = volumeInterval90(v, std::nan(""), std::nan(""));
  EXPECT_NEAR(bad.lo, 0.32 * v, 1e-12);
  EXPECT_NEAR(bad.hi, 1.80 * v, 1e-12);
  // A fit sized by its axis bound: its volume is nearly a floor, the interval reaches far above.
  const VolumeInterval floor = volumeInterval90(v, 1.0, 0.002, true);
  EXPECT_LE(floor.lo, 0.91 * v);
  EXPECT_GE(floor.hi, 2.5 * v);
}

TEST(VolumeInterval, AcceptedFitsOfThePipelineCarryIt) {
  const Superellipsoid a = Superellipsoid::sphere(0.04, Eigen::Vector3d(0, 0, 0.5));
  FruitShapePipeline pipeline;
  PointList cloud;
  for (const auto& p : a.sampleSurface(3000))
    if (p.z() > 0.49) cloud.push_back(p);  // seen a little beyond its upper half
  const auto& fruits = pipeline.update(cloud);
  ASSERT_EQ(fruits.size(), 1u);
  ASSERT_TRUE(fruits[0].accepted) << fruits[0].reason;
  EXPECT_LT(fruits[0].volume_lo, fruits[0].volume);
  EXPECT_GT(fruits[0].volume_hi, fruits[0].volume);
  EXPECT_LE(fruits[0].volume_lo, a.volume());
  EXPECT_GE(fruits[0].volume_hi, a.volume());
  EXPECT_GT(fruits[0].center_r90, 0.0);
  EXPECT_LE((fruits[0].center() - a.t).norm(), fruits[0].center_r90);
  // No unseen surface asked for (no targets): the fruit still says how far to trust it.
  PipelineParams no_samples;
  no_samples.missing.samples = 0;
  FruitShapePipeline without(no_samples);
  const auto& same = without.update(cloud);
  ASSERT_EQ(same.size(), 1u);
  EXPECT_TRUE(same[0].missing_surface.empty());
  EXPECT_EQ(same[0].volume_lo, fruits[0].volume_lo);
  EXPECT_EQ(same[0].volume_hi, fruits[0].volume_hi);
  EXPECT_EQ(same[0].center_r90, fruits[0].center_r90);
}

TEST(CenterUncertainty, ShrinksAsMoreOfTheFruitIsSeenAndGrowsWithTheResidual) {
  for (const double rms : {0.002, 0.0045, 0.007}) {
    double before = 1.0;
    for (int i = 0; i <= 20; ++i) {
      const double seen = 0.05 * i, r = centerRadius90(seen, rms);
      EXPECT_LE(r, before) << "seen " << seen << " rms " << rms;
      before = r;
    }
  }
  for (int i = 0; i <= 20; ++i) {
    EXPECT_LE(centerRadius90(0.05 * i, 0.002), centerRadius90(0.05 * i, 0.0045)) << "seen " << 0.05 * i;
    EXPECT_LE(centerRadius90(0.05 * i, 0.0045), centerRadius90(0.05 * i, 0.007)) << "seen " << 0.05 * i;
  }
  EXPECT_NEAR(centerRadius90(1.0, 0.002), 0.0025, 1e-12);  // a fruit seen all round: a few millimetres
  EXPECT_NEAR(centerRadius90(0.75, 0.0045), 0.0095, 1e-12);  // a knot
  EXPECT_NEAR(centerRadius90(0.5, 0.002), 0.01025, 1e-12);  // half way between two knots
  EXPECT_NEAR(centerRadius90(std::nan(""), std::nan("")), 0.020, 1e-12);  // nonsense in, the widest out
  EXPECT_GE(centerRadius90(1.0, 0.002, true), 0.019);  // placed by a patch of a larger fruit
}

// Random fruit-like superellipsoids seen from one side over a third to all of their surface,
// 1.5 mm noise on 4 mm voxels, through the pipeline: the true centre lies within the radius for
// about nine in ten, and the radius is not made large to get there.
TEST(CenterUncertainty, HoldsTheTrueCentreOfMostRandomFruits) {
  int inside = 0, fitted = 0;
  std::vector<double> radii;
  for (int i = 0; i < 40; ++i) {
    std::mt19937 rng(4000 + i);
    const Superellipsoid truth = randomSuperellipsoid(rng, Eigen::Vector3d(0.1, 0.2, 0.6));
    ScanParams scan;
    scan.noise_sigma = 0.0015;
    scan.visible_fraction = 0.35 + 0.65 * std::uniform_real_distribution<double>(0.0, 1.0)(rng);
    scan.view_dir = Eigen::Vector3d(std::cos(i), std::sin(i), 0.5);
    scan.seed = 5000 + i;
    FruitShapePipeline pipeline;
    const auto& fruits = pipeline.update(scanFruit(SyntheticFruit::fromSuperellipsoid(truth), scan));
    if (fruits.size() != 1 || !fruits[0].accepted) continue;
    ++fitted;
    inside += (fruits[0].center() - truth.t).norm() <= fruits[0].center_r90;
    radii.push_back(fruits[0].center_r90);
  }
  ASSERT_GE(fitted, 36);
  EXPECT_GE(inside, static_cast<int>(0.8 * fitted)) << inside << " of " << fitted;
  std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
  EXPECT_LT(radii[radii.size() / 2], 0.010);
  std::printf("[ report   ] true centre within the 90 %% radius: %d of %d, median radius %.1f mm\n", inside, fitted,
              1e3 * radii[radii.size() / 2]);
}
