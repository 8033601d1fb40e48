// Which predicted surface becomes the planner's targets (shape_targets.h): settled fruits hand
// over nothing, a cap spreads each fruit's targets, targets sit `offset` outside the surface
// along its outward normal and carry that normal as the side to view them from. And how far to
// trust a fit: the 90 % volume interval with the log-volume spread it is read from
// (volume_interval.h), and the centre radius (center_uncertainty.h).
#include <fruit_shape_completion/center_uncertainty.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>
#include <fruit_shape_completion/missing_surface.h>
#include <fruit_shape_completion/shape_targets.h>
#include <fruit_shape_completion/superellipsoid_fit.h>
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
                   +[](ShapeTargetParams& q) { q.view_max_range = 0.0; },
                   +[](ShapeTargetParams& q) { q.view_clearance = -0.1; },
                   +[](ShapeTargetParams& q) { q.view_clearance = 0.6; },
                   +[](ShapeTargetParams& q) { q.view_clearance = NAN; }}) {
    p = ShapeTargetParams();
    bad(p);
    EXPECT_THROW(p.validate(), std::invalid_argument);
  }
}

TEST(VolumeInterval, WidensWithTheSpreadAndTheResidualAndNeverAsMoreIsSeen) {
  const double v = 2e-4;
  const std::vector<double> spreads = {0.001, 0.01, 0.02, 0.04, 0.08, 0.2, 0.5, 2.0};
  const std::vector<double> seens = {0.0, 0.3, 0.5, 0.7, 0.9, 1.0};
  const std::vector<double> residuals = {0.0005, 0.002, 0.004, 0.006, 0.012};
  auto width = [&](double spread, double seen, double rms) {
    const VolumeInterval ci = volumeInterval90(v, seen, rms, spread);
    return ci.hi - ci.lo;
  };
  for (double spread : spreads)
    for (double seen : seens)
      for (double rms : residuals) {
        const VolumeInterval ci = volumeInterval90(v, seen, rms, spread);
        EXPECT_LT(ci.lo, v) << spread << ' ' << seen << ' ' << rms;  // the fit itself is always inside
        EXPECT_GT(ci.hi, v) << spread << ' ' << seen << ' ' << rms;
      }
  for (std::size_t i = 1; i < spreads.size(); ++i)
    for (double seen : seens)
      for (double rms : residuals)
        EXPECT_GE(width(spreads[i], seen, rms), width(spreads[i - 1], seen, rms) - 1e-15) << spreads[i];
  for (std::size_t i = 1; i < seens.size(); ++i)
    for (double spread : spreads)
      for (double rms : residuals)
        EXPECT_LE(width(spread, seens[i], rms), width(spread, seens[i - 1], rms) + 1e-15) << seens[i];
  for (std::size_t i = 1; i < residuals.size(); ++i)
    for (double spread : spreads)
      for (double seen : seens)
        EXPECT_GE(width(spread, seen, residuals[i]), width(spread, seen, residuals[i - 1]) - 1e-15) << residuals[i];
  // Fewer views never narrow it; a cloud given whole (no count) reads as seen in many views.
  for (double spread : spreads)
    for (double seen : seens)
      for (double rms : residuals) {
        const VolumeInterval cloud = volumeInterval90(v, seen, rms, spread, false, 0);
        for (int views = 1; views <= 12; ++views) {
          const VolumeInterval fewer = volumeInterval90(v, seen, rms, spread, false, views);
          const VolumeInterval more = volumeInterval90(v, seen, rms, spread, false, views + 1);
          EXPECT_LE(fewer.lo, more.lo) << views;
          EXPECT_GE(fewer.hi, more.hi) << views;
        }
        const VolumeInterval many = volumeInterval90(v, seen, rms, spread, false, 50);
        EXPECT_EQ(cloud.lo, many.lo);
        EXPECT_EQ(cloud.hi, many.hi);
      }
  // The calibration's figures (volume_interval.cpp): a fruit seen all round whose points pin its
  // size down, about -5 / +12 % (from a cloud, or seen in six views or more), -20 / +76 % seen in
  // one view; half seen with its depth left free, several times that.
  const VolumeInterval pinned = volumeInterval90(v, 1.0, 0.002, 0.015);
  const VolumeInterval one_view = volumeInterval90(v, 1.0, 0.002, 0.015, false, 1);
  const VolumeInterval loose = volumeInterval90(v, 0.5, 0.003, 0.15);
  EXPECT_NEAR(pinned.lo / v, 0.950, 0.001);
  EXPECT_NEAR(pinned.hi / v, 1.115, 0.001);
  EXPECT_EQ(volumeInterval90(v, 1.0, 0.002, 0.015, false, 6).lo, pinned.lo);
  EXPECT_NEAR(one_view.lo / v, 0.803, 0.001);
  EXPECT_NEAR(one_view.hi / v, 1.763, 0.001);
  EXPECT_GT(0.5 * (loose.hi - loose.lo) / v, 0.25);
  // Nonsense in, the widest interval out.
  const VolumeInterval bad = volumeInterval90(v, std::nan(""), std::nan(""), std::nan(""));
  const VolumeInterval widest = volumeInterval90(v, 0.0, 1.0, 1e9);
  EXPECT_EQ(bad.lo, widest.lo);
  EXPECT_EQ(bad.hi, widest.hi);
  // A fit sized by its axis bound: its volume is nearly a floor, the interval reaches far above.
  const VolumeInterval floor = volumeInterval90(v, 1.0, 0.002, 0.015, true);
  EXPECT_LE(floor.lo, pinned.lo);
  EXPECT_GE(floor.hi, 2.0 * v);
}

// The spread follows the scatter it stands for: over noisy scans of one fully seen fruit, the
// fitted log volumes scatter about as much as each fit's spread says; it doubles with the noise
// (above its floor), grows as less of the fruit is seen, and is undefined for fewer points than
// parameters.
TEST(VolumeInterval, TheSpreadFollowsTheScatterOfRepeatedFits) {
  Superellipsoid truth;
  truth.a = 0.035, truth.b = 0.03, truth.c = 0.04, truth.e1 = 0.7, truth.e2 = 0.6;
  truth.t = Eigen::Vector3d(0.1, 0.2, 0.6);
  truth.rpy = Eigen::Vector3d(0.3, -0.2, 0.5);
  auto scanned = [&](double noise, double seen, unsigned seed, bool thin = true) {
    ScanParams scan;
    scan.noise_sigma = noise;
    scan.visible_fraction = seen;
    scan.voxel = 0.0;
    scan.view_dir = Eigen::Vector3d(1, 0.3, 0.2);
    scan.seed = seed;
    PointList pts = scanFruit(SyntheticFruit::fromSuperellipsoid(truth), scan);
    if (!thin) return pts;
    PointList some;  // a few hundred points, as the fit's final solve uses
    for (std::size_t i = 0; i < pts.size(); i += std::max<std::size_t>(1, pts.size() / 300)) some.push_back(pts[i]);
    return some;
  };
  std::vector<double> logs, spreads;
  for (unsigned k = 0; k < 30; ++k) {
    const PointList pts = scanned(0.002, 1.0, 100 + k);
    const FitResult fit = fitSuperellipsoid(pts, truth.t, FitParams(), &truth);
    ASSERT_TRUE(fit.accepted) << fit.reason;
    logs.push_back(std::log(fit.shape.volume()));
    spreads.push_back(logVolumeSpread(pts, fit.shape));
  }
  double mean = 0, var = 0, spread = 0;
  for (double l : logs) mean += l / logs.size();
  for (double l : logs) var += (l - mean) * (l - mean) / (logs.size() - 1);
  for (double s : spreads) spread += s / spreads.size();
  EXPECT_GT(spread, 0.5 * std::sqrt(var));
  EXPECT_LT(spread, 2.0 * std::sqrt(var));
  std::printf("[ report   ] scatter of log volume over 30 fits %.4f, mean spread %.4f\n", std::sqrt(var), spread);
  const double quiet = logVolumeSpread(scanned(0.0025, 1.0, 7), truth);
  const double noisy = logVolumeSpread(scanned(0.005, 1.0, 7), truth);
  EXPECT_NEAR(noisy / quiet, 2.0, 0.3);
  EXPECT_GT(logVolumeSpread(scanned(0.0025, 0.4, 7), truth), 1.5 * quiet);
  // A cloud cleaner than any the interval was made from (1.75 mm RMS at best) reads as that.
  const double clean = logVolumeSpread(scanned(0.0, 1.0, 7), truth);
  EXPECT_GT(clean, 0.5 * quiet);
  EXPECT_NEAR(clean, logVolumeSpread(scanned(0.0005, 1.0, 7), truth), 0.1 * clean);
  // Taken on kSpreadPoints whatever the cloud's size: the whole scan (tens of thousands of
  // points) reads as its thinned few hundred do.
  const PointList dense = scanned(0.0025, 1.0, 7, false);
  ASSERT_GT(dense.size(), 20u * kSpreadPoints);
  EXPECT_NEAR(logVolumeSpread(dense, truth), quiet, 0.25 * quiet);
  const PointList all = scanned(0.002, 1.0, 7);
  const PointList few(all.begin(), all.begin() + 11);
  EXPECT_TRUE(std::isnan(logVolumeSpread(few, truth)));
  PointList with_nan = scanned(0.002, 1.0, 7);
  with_nan.push_back(Point::Constant(std::nan("")));
  EXPECT_TRUE(std::isfinite(logVolumeSpread(with_nan, truth)));
}

namespace {

// Random fruit-like superellipsoids seen from one side over a third to all of their surface,
// 1.5 mm noise on 4 mm voxels, each through its own pipeline: the truths and their single
// accepted fits (40 drawn, once for the tests that read them).
struct RandomFruitFit {
  Superellipsoid truth;
  FruitEstimate fit;
};
const std::vector<RandomFruitFit>& fitRandomFruits() {
  static const std::vector<RandomFruitFit> fits = [] {
  std::vector<RandomFruitFit> out;
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
    if (fruits.size() == 1 && fruits[0].accepted) out.push_back({truth, fruits[0]});
  }
  return out;
  }();
  return fits;
}

}  // namespace

// The true volume of such fruits lies inside the interval for about nine in ten, and the
// interval is not made wide to get there.
TEST(VolumeInterval, HoldsTheTrueVolumeOfMostRandomFruits) {
  const std::vector<RandomFruitFit>& fits = fitRandomFruits();
  ASSERT_GE(fits.size(), 36u);
  int inside = 0;
  std::vector<double> half_widths;
  for (const auto& f : fits) {
    inside += f.truth.volume() >= f.fit.volume_lo && f.truth.volume() <= f.fit.volume_hi;
    half_widths.push_back(0.5 * (f.fit.volume_hi - f.fit.volume_lo) / f.fit.volume);
  }
  EXPECT_GE(inside, static_cast<int>(0.8 * fits.size())) << inside << " of " << fits.size();
  std::nth_element(half_widths.begin(), half_widths.begin() + half_widths.size() / 2, half_widths.end());
  EXPECT_LT(half_widths[half_widths.size() / 2], 0.15);
  std::printf("[ report   ] true volume inside the 90 %% interval: %d of %zu, median half-width %.1f %%\n", inside,
              fits.size(), 100 * half_widths[half_widths.size() / 2]);
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
  EXPECT_NEAR(centerRadius90(0.75, 0.0045), 0.0075, 1e-12);  // a knot
  EXPECT_NEAR(centerRadius90(0.5, 0.002), 0.0105, 1e-12);  // half way between two knots
  EXPECT_NEAR(centerRadius90(std::nan(""), std::nan("")), 0.0185, 1e-12);  // nonsense in, the widest out
  EXPECT_NEAR(centerRadius90(1.0, 0.002, true), 0.0205, 1e-12);  // placed by a patch of a larger fruit
}

// The true centre of the same random fruits lies within the radius for about nine in ten, and
// the radius is not made large to get there.
TEST(CenterUncertainty, HoldsTheTrueCentreOfMostRandomFruits) {
  const std::vector<RandomFruitFit>& fits = fitRandomFruits();
  ASSERT_GE(fits.size(), 36u);
  int inside = 0;
  std::vector<double> radii;
  for (const auto& f : fits) {
    inside += (f.fit.center() - f.truth.t).norm() <= f.fit.center_r90;
    radii.push_back(f.fit.center_r90);
  }
  EXPECT_GE(inside, static_cast<int>(0.8 * fits.size())) << inside << " of " << fits.size();
  std::nth_element(radii.begin(), radii.begin() + radii.size() / 2, radii.end());
  EXPECT_LT(radii[radii.size() / 2], 0.010);
  std::printf("[ report   ] true centre within the 90 %% radius: %d of %zu, median radius %.1f mm\n", inside,
              fits.size(), 1e3 * radii[radii.size() / 2]);
}
