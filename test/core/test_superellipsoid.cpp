#include <fruit_shape_completion/superellipsoid.h>
#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>

using namespace fruit_shape_completion;

TEST(Superellipsoid, EllipsoidVolumeIsFourThirdsPiAbc) {
  Superellipsoid se;
  se.a = 0.03; se.b = 0.04; se.c = 0.05; se.e1 = 1.0; se.e2 = 1.0;
  EXPECT_NEAR(se.volume(), 4.0 / 3.0 * M_PI * 0.03 * 0.04 * 0.05, 1e-12);
}

TEST(Superellipsoid, VolumeFormulaMatchesNumericalIntegration) {
  std::mt19937 rng(5);
  for (int i = 0; i < 10; ++i) {
    const Superellipsoid se = randomSuperellipsoid(rng, Eigen::Vector3d(1, 2, 3), {0.02, 0.15, 2.0, 0.3, 0.9});
    const double numeric = SyntheticFruit::fromSuperellipsoid(se).volume(400000);
    EXPECT_NEAR(se.volume(), numeric, 2e-3 * numeric) << "case " << i;
  }
}

TEST(Superellipsoid, RotationConventionIsZYXFixedAxes) {
  Superellipsoid se;
  se.rpy = Eigen::Vector3d(0.3, -0.7, 1.9);
  const Eigen::Matrix3d expected = (Eigen::AngleAxisd(1.9, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(-0.7, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  EXPECT_LT((se.rotation() - expected).norm(), 1e-12);
  // yaw 90 degrees maps local x onto world y
  se.rpy = Eigen::Vector3d(0, 0, M_PI / 2);
  se.t = Eigen::Vector3d(1, 0, 0);
  EXPECT_LT((se.toWorld(Eigen::Vector3d(0.1, 0, 0)) - Eigen::Vector3d(1, 0.1, 0)).norm(), 1e-12);
  EXPECT_LT((se.toLocal(se.toWorld(Eigen::Vector3d(0.1, 0.2, 0.3))) - Eigen::Vector3d(0.1, 0.2, 0.3)).norm(), 1e-12);
}

TEST(Superellipsoid, SamplesLieOnTheSurfaceAndCoverIt) {
  std::mt19937 rng(11);
  const Superellipsoid se = randomSuperellipsoid(rng, Eigen::Vector3d(0.2, -0.1, 0.4));
  const PointList s = se.sampleSurface(300);
  ASSERT_EQ(s.size(), 300u);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : s) {
    EXPECT_NEAR(se.implicit(p), 1.0, 1e-9);
    EXPECT_LT(se.radialDistance(p), 1e-9);
    mean += p / 300.0;
  }
  // Directions cover the sphere evenly: the mean sample is close to the centre.
  EXPECT_LT((mean - se.t).norm(), 0.1 * std::min({se.a, se.b, se.c}));
}

TEST(Superellipsoid, RadialDistanceAndInsideTest) {
  Superellipsoid se;
  se.a = 0.04; se.b = 0.05; se.c = 0.06; se.e1 = 0.6; se.e2 = 0.8;
  se.t = Eigen::Vector3d(0.5, 0.5, 0.5);
  se.rpy = Eigen::Vector3d(0.1, 0.2, 0.3);
  const Eigen::Vector3d s = se.toWorld(se.surfacePointLocal(Eigen::Vector3d(1, 2, -1)));
  const Eigen::Vector3d out = se.t + 2.0 * (s - se.t);
  const Eigen::Vector3d in = se.t + 0.5 * (s - se.t);
  EXPECT_NEAR(se.radialDistance(out), (s - se.t).norm(), 1e-9);
  EXPECT_NEAR(se.radialDistance(in), 0.5 * (s - se.t).norm(), 1e-9);
  EXPECT_FALSE(se.isInside(out));
  EXPECT_TRUE(se.isInside(in));
  EXPECT_TRUE(se.isInside(se.t));
}
