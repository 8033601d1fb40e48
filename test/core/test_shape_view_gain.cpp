// What a view gains from the predicted surface it would see (shape_view_gain.h): a half-seen
// fruit's unseen half counts from below, not from above, not outside the view's cone or range,
// and not through an occupied map; the gains of a fruit's targets add up to its unseen share.
#include <fruit_shape_completion/missing_surface.h>
#include <fruit_shape_completion/shape_targets.h>
#include <fruit_shape_completion/shape_view_gain.h>
#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <cmath>

using namespace fruit_shape_completion;

namespace {

// A 4 cm sphere at z = 0.5 m seen on its upper half only.
FruitEstimate upperHalfSeen() {
  FruitEstimate f;
  f.shape = Superellipsoid::sphere(0.04, Eigen::Vector3d(0, 0, 0.5));
  f.accepted = true;
  PointList seen;
  for (const auto& p : f.shape.sampleSurface(2000))
    if (p.z() > 0.5) seen.push_back(p);
  f.points = seen;
  f.missing_surface = predictMissingSurface(f.shape, f.points, MissingSurfaceParams());
  return f;
}

ShapeTargetParams withGain(double gain) {
  ShapeTargetParams p;
  p.view_gain = gain;
  return p;
}

double sum(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return s;
}

}  // namespace

TEST(ShapeViewGain, AFruitsTargetsAddUpToItsUnseenShareTimesTheGain) {
  const FruitEstimate f = upperHalfSeen();
  const double unseen = static_cast<double>(f.missing_surface.size()) / 300.0;
  ASSERT_GT(unseen, 0.2);
  ASSERT_LT(unseen, 0.5);
  const ShapeTargets all = selectShapeTargets({f}, 300, withGain(2.0));
  ASSERT_EQ(all.gains.size(), all.points.size());
  EXPECT_NEAR(sum(all.gains), 2.0 * unseen, 1e-9);
  ShapeTargetParams capped = withGain(2.0);
  capped.per_fruit = 10;
  const ShapeTargets ten = selectShapeTargets({f}, 300, capped);
  ASSERT_EQ(ten.gains.size(), 10u);
  EXPECT_NEAR(sum(ten.gains), 2.0 * unseen, 1e-9);
  EXPECT_TRUE(selectShapeTargets({f}, 300, withGain(0.0)).gains.empty());  // no view gain: no gains
}

TEST(ShapeViewGain, ViewFromBelowSeesTheUnseenHalfAndNoOtherViewDoes) {
  const FruitEstimate f = upperHalfSeen();
  const ShapeTargets t = selectShapeTargets({f}, 300, withGain(1.0));
  const double whole = sum(t.gains);
  const Eigen::Vector3d below(0, 0, 0.1), up(0, 0, 1);
  // From 40 cm below a 4 cm sphere the camera sees all of it but a band 10 degrees wide at the
  // equator, where the unseen samples are fewest.
  const double from_below = shapeViewGain(t, below, up);
  EXPECT_GT(from_below, 0.8 * whole);
  EXPECT_LE(from_below, whole + 1e-12);
  EXPECT_EQ(shapeViewGain(t, Eigen::Vector3d(0, 0, 0.9), -up), 0.0);        // facing away
  EXPECT_EQ(shapeViewGain(t, below, Eigen::Vector3d(1, 0, 0)), 0.0);         // outside the cone
  EXPECT_EQ(shapeViewGain(t, Eigen::Vector3d(0, 0, -0.6), up), 0.0);         // beyond the 1 m range
  // From the side, about half the unseen half faces the camera.
  const double side = shapeViewGain(t, Eigen::Vector3d(0.4, 0, 0.5), Eigen::Vector3d(-1, 0, 0));
  EXPECT_GT(side, 0.3 * whole);
  EXPECT_LT(side, 0.7 * whole);
  // Bad views count nothing.
  EXPECT_EQ(shapeViewGain(t, Eigen::Vector3d(NAN, 0, 0), up), 0.0);
  EXPECT_EQ(shapeViewGain(t, below, Eigen::Vector3d::Zero()), 0.0);
}

TEST(ShapeViewGain, LinesOfSightThroughAnOccupiedMapCountOnlyWhereClear) {
  const FruitEstimate f = upperHalfSeen();
  const ShapeTargets t = selectShapeTargets({f}, 300, withGain(1.0));
  const Eigen::Vector3d below(0, 0, 0.1), up(0, 0, 1);
  const double open = shapeViewGain(t, below, up);
  octomap::OcTree tree(0.01);
  tree.updateNode(octomap::point3d(0.5f, 0.5f, 0.5f), false);  // a map, but nothing in the way
  EXPECT_DOUBLE_EQ(shapeViewGain(t, below, up, occupiedCellsBlock(tree)), open);
  // A leaf covering x < 0 at z = 0.3 m hides about half of the lower half.
  for (int i = -15; i < 0; ++i)
    for (int j = -15; j <= 15; ++j)
      tree.updateNode(octomap::point3d(0.01f * i + 0.005f, 0.01f * j + 0.005f, 0.305f), true);
  const double half = shapeViewGain(t, below, up, occupiedCellsBlock(tree));
  EXPECT_GT(half, 0.3 * open);
  EXPECT_LT(half, 0.7 * open);
  // Covering all of it hides everything.
  for (int i = 0; i <= 15; ++i)
    for (int j = -15; j <= 15; ++j)
      tree.updateNode(octomap::point3d(0.01f * i + 0.005f, 0.01f * j + 0.005f, 0.305f), true);
  EXPECT_EQ(shapeViewGain(t, below, up, occupiedCellsBlock(tree)), 0.0);
}

TEST(ShapeViewGain, AViewAmongTheMappedPlantGainsNothingWithAClearance) {
  const FruitEstimate f = upperHalfSeen();
  ShapeTargetParams p = withGain(1.0);
  p.view_clearance = 0.1;
  const ShapeTargets t = selectShapeTargets({f}, 300, p);
  ASSERT_DOUBLE_EQ(t.view_clearance, 0.1);
  const Eigen::Vector3d below(0, 0, 0.1), up(0, 0, 1);
  const double open = shapeViewGain(t, below, up);
  ASSERT_GT(open, 0.0);
  octomap::OcTree tree(0.01);
  // An occupied cell 12 cm beside the camera, out of the line of sight: farther than the clearance.
  tree.updateNode(octomap::point3d(0.125f, 0.005f, 0.105f), true);
  EXPECT_DOUBLE_EQ(shapeViewGain(t, below, up, occupiedCellsBlock(tree), occupiedCellsNear(tree)), open);
  // One inside the box searched but outside the sphere: its box comes to 11.3 cm.
  tree.updateNode(octomap::point3d(0.085f, 0.085f, 0.105f), true);
  EXPECT_DOUBLE_EQ(shapeViewGain(t, below, up, occupiedCellsBlock(tree), occupiedCellsNear(tree)), open);
  // A cell whose box comes to 9 cm: within it, and the view gains nothing (lines of sight not
  // traced: the clearance alone decides).
  tree.updateNode(octomap::point3d(0.095f, 0.005f, 0.105f), true);
  EXPECT_EQ(shapeViewGain(t, below, up, nullptr, occupiedCellsNear(tree)), 0.0);
  // The box counts, not the centre: a cell from 10 to 11 cm (centre 10.5 cm) is within 10.4 cm.
  octomap::OcTree edge(0.01);
  edge.updateNode(octomap::point3d(0.105f, 0.005f, 0.105f), true);
  EXPECT_TRUE(occupiedCellsNear(edge)(below, 0.104));
  EXPECT_FALSE(occupiedCellsNear(edge)(below, 0.099));
  // A pruned 2 cm leaf (eight occupied children) counts by its whole box, 10 cm away, though its
  // centre is 11 cm away and a 1 cm box around that centre 10.5 cm.
  octomap::OcTree coarse(0.01);
  for (float dx : {0.105f, 0.115f})
    for (float dy : {0.005f, 0.015f})
      for (float dz : {0.105f, 0.115f}) coarse.updateNode(octomap::point3d(dx, dy, dz), true);
  coarse.prune();
  ASSERT_EQ(coarse.getNumLeafNodes(), 1u);
  EXPECT_TRUE(occupiedCellsNear(coarse)(below, 0.104));
  EXPECT_FALSE(occupiedCellsNear(coarse)(below, 0.099));
  // Beyond the tree's range (327 m at 1 cm), or at a non-finite point, a camera counts as crowded.
  EXPECT_TRUE(occupiedCellsNear(edge)(Eigen::Vector3d(400, 0, 0), 0.1));
  EXPECT_TRUE(occupiedCellsNear(edge)(Eigen::Vector3d(NAN, 0, 0), 0.1));
  // Free cells nearby do not count, and clearance 0 checks nothing.
  octomap::OcTree free_only(0.01);
  free_only.updateNode(octomap::point3d(0.005f, 0.005f, 0.105f), false);
  EXPECT_DOUBLE_EQ(shapeViewGain(t, below, up, nullptr, occupiedCellsNear(free_only)), open);
  p.view_clearance = 0.0;
  const ShapeTargets unchecked = selectShapeTargets({f}, 300, p);
  EXPECT_DOUBLE_EQ(shapeViewGain(unchecked, below, up, nullptr, occupiedCellsNear(tree)), open);
}
