// The stand-in's emulation of roi_viewpoint_planner's samplers and ROI_VICINITY_UTILITY on
// hand-built octrees, against values worked out from upstream's formulas
// (octomap_vpp RoiOcTree::computeInflatedRois, RoiVicinityUtility::computeRoiWeightedIG,
// RoiContourSampler, ContourSampler, computeSurfaceNormalDir, dirVecToQuat).
#include <fruit_shape_completion/instrument/planner/upstream_sampling.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <set>

using namespace fruit_shape_completion;
using namespace fruit_shape_completion::planner;

namespace {

constexpr double kRes = 0.01;

octomap::point3d cell(int x, int y, int z) {
  // Cell centres of a 1 cm tree: (i + 0.5) cm.
  return octomap::point3d(static_cast<float>((x + 0.5) * kRes), static_cast<float>((y + 0.5) * kRes),
                          static_cast<float>((z + 0.5) * kRes));
}
void setOccupied(RoiOcTree* t, int x, int y, int z, bool roi = false) {
  RoiOcTreeNode* n = t->updateNode(cell(x, y, z), true);
  if (roi) t->search(cell(x, y, z))->setRoiLogOdds(1.0f);
  (void)n;
}
// Seen free twice: occupancy 0.31. Seen free once, octomap's default miss gives 0.4 up to float
// rounding, which upstream's "occ > 0.4: unknown" test counts as unknown (setFreeOnce).
void setFree(RoiOcTree* t, int x, int y, int z) {
  t->updateNode(cell(x, y, z), false);
  t->updateNode(cell(x, y, z), false);
}
void setFreeOnce(RoiOcTree* t, int x, int y, int z) { t->updateNode(cell(x, y, z), false); }

ShapeTargets targetsAt(const PointList& points, const PointList& directions) {
  ShapeTargets t;
  t.points = points;
  t.directions = directions;
  return t;
}

// One target facing +y, worth 0.4 to a view that sees it (60 degree cone, 1 m).
ShapeTargets loneTargetWithGain(const Eigen::Vector3d& target, double clearance) {
  ShapeTargets t = targetsAt({target}, {Eigen::Vector3d(0, 1, 0)});
  t.gains = {0.4};
  t.view_cos_half_angle = std::cos(0.5);
  t.view_max_range = 1.0;
  t.view_clearance = clearance;
  return t;
}

sim::Workspace everywhere() {
  sim::Workspace w;
  w.box_min = Eigen::Vector3d::Constant(-5);
  w.box_max = Eigen::Vector3d::Constant(5);
  return w;
}

// The ROI candidates alone (no exploration samples), seed 5, the camera at `camera`.
SampledCandidates sampleRoiOnly(const RoiOcTree& tree, const ShapeTargets& t, const Eigen::Vector3d& camera) {
  UpstreamSamplingParams p;
  p.expl_samples = 0;
  std::mt19937 rng(5);
  return sampleUpstream(tree, everywhere(), t, camera, p, rng);
}

}  // namespace

// A solid 2 x 2 x 2 block of alike ROI voxels prunes into one leaf; upstream's ROI key set keeps
// all eight voxels however the tree prunes.
TEST(UpstreamSampling, APrunedRoiBlockGivesEachOfItsVoxels) {
  RoiOcTree tree(kRes);
  for (int x = 2; x < 4; ++x)
    for (int y = 0; y < 2; ++y)
      for (int z = 0; z < 2; ++z) setOccupied(&tree, x, y, z, true);
  setOccupied(&tree, 10, 10, 10, true);
  tree.prune();
  int pruned = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
    pruned += static_cast<int>(it.getDepth()) < static_cast<int>(tree.getTreeDepth());
  ASSERT_EQ(pruned, 1) << "the block did not prune: the test would not test the expansion";
  const auto keys = upstreamRoiKeys(tree);
  ASSERT_EQ(keys.size(), 9u);
  const octomap::OcTreeKey origin = tree.coordToKey(cell(0, 0, 0));
  std::set<std::array<int, 3>> got;
  for (const auto& k : keys) got.insert({k[0] - origin[0], k[1] - origin[1], k[2] - origin[2]});
  for (int x = 2; x < 4; ++x)
    for (int y = 0; y < 2; ++y)
      for (int z = 0; z < 2; ++z) EXPECT_EQ(got.count({x, y, z}), 1u) << x << " " << y << " " << z;
  EXPECT_EQ(got.count({10, 10, 10}), 1u);
}

TEST(UpstreamSampling, InflatedRoiValuesFallOneSixthPerFiveCentimetreStep) {
  // An ROI voxel at 1 cm inside the 5 cm cell [0, 5) cm; computeInflatedRois(0.05, 0.3):
  // step = 1 / 0.3 * 0.05 = 1/6 per unit of 26-neighbour offset length.
  RoiOcTree tree(kRes);
  setOccupied(&tree, 2, 2, 2, true);
  const auto keys = upstreamRoiKeys(tree);
  ASSERT_EQ(keys.size(), 1u);
  const InflatedRois inf(tree, keys, 0.05, 0.3);
  auto at5 = [&](int i, int j, int k) {
    return inf.value(octomap::point3d(static_cast<float>(0.025 + 0.05 * i), static_cast<float>(0.025 + 0.05 * j),
                                      static_cast<float>(0.025 + 0.05 * k)));
  };
  const double step = 1.0 / 6.0;
  EXPECT_NEAR(at5(0, 0, 0), 1.0, 1e-6);
  EXPECT_NEAR(at5(1, 0, 0), 1.0 - step, 1e-6);
  EXPECT_NEAR(at5(0, -1, 0), 1.0 - step, 1e-6);
  EXPECT_NEAR(at5(1, 1, 0), 1.0 - step * std::sqrt(2.0), 1e-6);
  EXPECT_NEAR(at5(1, 1, 1), 1.0 - step * std::sqrt(3.0), 1e-6);
  EXPECT_NEAR(at5(3, 0, 0), 0.5, 1e-5);
  // (2, 1, 0): one diagonal and one straight step beats three straight ones.
  EXPECT_NEAR(at5(2, 1, 0), 1.0 - step * (1.0 + std::sqrt(2.0)), 1e-5);
  EXPECT_NEAR(at5(5, 0, 0), 1.0 - 5 * step, 1e-5);
  EXPECT_EQ(at5(6, 0, 0), 0.0f);  // 1 - 6/6 = 0: beyond the influence radius, no node
  EXPECT_EQ(at5(7, 0, 0), 0.0f);
  // Two ROI cells: each 5 cm cell keeps the higher of the two values.
  setOccupied(&tree, 2 + 20, 2, 2, true);  // 4 cells of 5 cm further along x
  const InflatedRois two(tree, upstreamRoiKeys(tree), 0.05, 0.3);
  EXPECT_NEAR(two.value(octomap::point3d(0.025f + 0.05f * 2, 0.025f, 0.025f)), 1.0 - 2 * step, 1e-5);
  EXPECT_NEAR(two.value(octomap::point3d(0.025f + 0.05f * 3, 0.025f, 0.025f)), 1.0 - step, 1e-5);
}

TEST(UpstreamSampling, RoiWeightedGainCountsUnknownCellsUntilTheFirstOccupiedOne) {
  RoiOcTree tree(kRes);
  // Along x from cell 0 to cell 20 (the target's cell is not on the ray: 20 cells).
  // Cells 0-4 free, 5-9 unknown, 10 occupied, beyond unknown.
  for (int x = 0; x < 5; ++x) setFree(&tree, x, 0, 0);
  setOccupied(&tree, 10, 0, 0);
  const InflatedRois none(tree, {}, 0.05, 0.3);
  const Eigen::Vector3d origin(0.005, 0.005, 0.005), target(0.205, 0.005, 0.005);
  // Five unknown cells of weight 0.5 before the blocking one, over 20 cells.
  EXPECT_NEAR(roiWeightedGain(tree, none, origin, target), 5 * 0.5 / 20.0, 1e-9);
  // A cell seen free only once still counts as unknown there, as in upstream.
  RoiOcTree once(kRes);
  for (int x = 0; x < 5; ++x) setFreeOnce(&once, x, 0, 0);
  setOccupied(&once, 10, 0, 0);
  EXPECT_GT(once.search(cell(0, 0, 0))->getOccupancy(), 0.4);
  EXPECT_NEAR(roiWeightedGain(once, none, origin, target), 10 * 0.5 / 20.0, 1e-9);

  // Nothing blocks: cells 0-4 and 10 free, 5-9 and 11-19 unknown (14).
  RoiOcTree open(kRes);
  for (int x = 0; x < 5; ++x) setFree(&open, x, 0, 0);
  setFree(&open, 10, 0, 0);
  EXPECT_NEAR(roiWeightedGain(open, none, origin, target), 14 * 0.5 / 20.0, 1e-9);

  // An ROI cell next to the ray raises the weights of unknown cells near it: 0.5 + 0.5 x value.
  setOccupied(&open, 15, 1, 0, true);  // in the 5 cm cell x in [15, 20) cm
  const InflatedRois inf(open, upstreamRoiKeys(open), 0.05, 0.3);
  double expected = 0.0;
  for (int x = 0; x < 20; ++x) {
    if (x < 5 || x == 10) continue;  // free
    expected += 0.5 + 0.5 * inf.value(cell(x, 0, 0));
  }
  EXPECT_NEAR(inf.value(cell(16, 0, 0)), 1.0, 1e-6);
  EXPECT_NEAR(inf.value(cell(12, 0, 0)), 1.0 - 1.0 / 6.0, 1e-6);
  EXPECT_NEAR(roiWeightedGain(open, inf, origin, target), expected / 20.0, 1e-9);
  EXPECT_GT(expected / 20.0, 14 * 0.5 / 20.0);
}

TEST(UpstreamSampling, RoiContourPoolIsFreeSixNeighboursOfRoiWithAnUnknownSixNeighbour) {
  RoiOcTree tree(kRes);
  setOccupied(&tree, 0, 0, 0, true);
  setFree(&tree, 1, 0, 0);   // free, its other neighbours unknown: in the pool
  setFree(&tree, 1, 1, 0);   // a diagonal neighbour of the ROI: not a 6-neighbour
  setFree(&tree, 0, -1, 0);  // free, but all its 6-neighbours known: not in the pool
  for (const auto& o : {std::array<int, 3>{0, -2, 0}, {1, -1, 0}, {-1, -1, 0}, {0, -1, 1}, {0, -1, -1}})
    setFree(&tree, o[0], o[1], o[2]);
  const PointList pool = roiContourPool(tree, upstreamRoiKeys(tree));
  ASSERT_EQ(pool.size(), 1u);
  EXPECT_NEAR((pool[0] - Eigen::Vector3d(0.015, 0.005, 0.005)).norm(), 0.0, 1e-6);
}

TEST(UpstreamSampling, ContourKeysAndTheirNormalPointAwayFromTheSurface) {
  RoiOcTree tree(kRes);
  // A wall of occupied cells at x = 0 (y, z in -2..2); free cells at x = 1 in front of it.
  for (int y = -2; y <= 2; ++y)
    for (int z = -2; z <= 2; ++z) {
      setOccupied(&tree, 0, y, z);
      setFree(&tree, 1, y, z);
    }
  const auto keys = contourKeys(tree, everywhere());
  // Every free cell has the wall at -x and unknown at +x.
  EXPECT_EQ(keys.size(), 25u);
  for (const auto& k : keys) {
    const Eigen::Vector3d c = tree.center(k);
    EXPECT_NEAR(c.x(), 0.015, 1e-6);
    const Eigen::Vector3d n = surfaceNormalDir(tree, k);
    if (std::abs(c.y() - 0.005) < 1e-6 && std::abs(c.z() - 0.005) < 1e-6) {
      // Inside the wall: occupied 18-neighbours at (-1,0,0), (-1,+-1,0), (-1,0,+-1): sum (-5,0,0).
      EXPECT_NEAR((n - Eigen::Vector3d(1, 0, 0)).norm(), 0.0, 1e-9);
    }
    EXPECT_GT(n.x(), 0.5);
  }
  // A region that leaves the wall's front out finds none.
  sim::Workspace behind = everywhere();
  behind.box_max.x() = 0.0;
  EXPECT_TRUE(contourKeys(tree, behind).empty());
}

TEST(UpstreamSampling, TurnTowardsIsTheSmallestRotationThatAimsTheCamera) {
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix();
  const Eigen::Vector3d dir = Eigen::Vector3d(0.5, -0.2, 0.8).normalized();
  const Eigen::Matrix3d t = turnTowards(r, dir);
  EXPECT_NEAR((t.col(2) - dir).norm(), 0.0, 1e-12);
  EXPECT_NEAR((t * t.transpose() - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
  // The rotation axis (old view x new view) is left where it was: no roll beyond the turn.
  const Eigen::Vector3d axis = r.col(2).cross(dir).normalized();
  const Eigen::Matrix3d delta = t * r.transpose();
  EXPECT_NEAR((delta * axis - axis).norm(), 0.0, 1e-12);
  EXPECT_NEAR((turnTowards(r, r.col(2)) - r).norm(), 0.0, 1e-12);
  EXPECT_NEAR((turnTowards(r, -r.col(2)).col(2) + r.col(2)).norm(), 0.0, 1e-12);
}

TEST(UpstreamSampling, RoiViewsAreUsedOnlyWhenTheBestScoresAboveTheThreshold) {
  // A fruit cell seen from one side; the ROI views toward its unseen side score by the unknown
  // cells on their rays, minus 0.2 per metre from the camera.
  RoiOcTree tree(kRes);
  for (int y = -3; y <= 3; ++y)
    for (int z = -3; z <= 3; ++z) setOccupied(&tree, 0, y, z, y == 0 && z == 0);
  for (int y = -3; y <= 3; ++y)
    for (int z = -3; z <= 3; ++z) setFree(&tree, 1, y, z);  // beyond x = 1 unknown
  UpstreamSamplingParams p;
  std::mt19937 rng(3);
  const Eigen::Vector3d near_camera(0.3, 0.0, 0.0);
  const SampledCandidates s = sampleUpstream(tree, everywhere(), {}, near_camera, p, rng);
  ASSERT_FALSE(s.roi.empty());
  EXPECT_EQ(s.roi.size(), 100u);  // every sample inside the workspace
  for (std::size_t i = 1; i < s.roi.size(); ++i) EXPECT_GE(s.roi[i - 1].utility, s.roi[i].utility);
  for (const auto& v : s.roi) {
    const double d = (v.origin - v.target).norm();
    EXPECT_GE(d, 0.3 - 1e-9);
    EXPECT_LE(d, 0.5 + 1e-9);
    EXPECT_NEAR(v.utility, v.gain - 0.2 * (v.origin - near_camera).norm(), 1e-12);
  }
  EXPECT_EQ(s.use_roi, s.roi.front().utility > 0.2);
  // A camera 10 m away: every utility drops by ~2, the ROI views are not used.
  std::mt19937 rng2(3);
  const SampledCandidates far = sampleUpstream(tree, everywhere(), {}, Eigen::Vector3d(10, 0, 0), p, rng2);
  EXPECT_FALSE(far.use_roi);
  EXPECT_EQ(&far.chosen(), &far.exploration);
  // Extra targets join the ROI pool.
  std::mt19937 rng3(3);
  const SampledCandidates extra =
      sampleUpstream(tree, everywhere(), targetsAt({Eigen::Vector3d(-0.05, 0, 0)}, {}), near_camera, p, rng3);
  EXPECT_EQ(extra.roi_pool, s.roi_pool + 1);
}

TEST(UpstreamSampling, AShapeTargetWithADirectionIsViewedFromTheSideItFaces) {
  // An empty map: every sample is kept; the one extra target faces +y.
  RoiOcTree tree(kRes);
  setFree(&tree, 0, 0, 0);
  const Eigen::Vector3d target(0.3, 0.2, 0.5), facing(0, 1, 0);
  UpstreamSamplingParams p;
  p.expl_samples = 0;
  std::mt19937 rng(5);
  const SampledCandidates s = sampleUpstream(tree, everywhere(), targetsAt({target}, {facing}), target, p, rng);
  ASSERT_EQ(s.roi.size(), 100u);
  for (const auto& v : s.roi) {
    EXPECT_TRUE(v.shape_target);
    EXPECT_GE((v.origin - target).dot(facing), 0.0);
    EXPECT_NEAR((v.direction + (v.origin - target).normalized()).norm(), 0.0, 1e-9);
  }
  // Without a direction, both sides.
  std::mt19937 rng2(5);
  const SampledCandidates any =
      sampleUpstream(tree, everywhere(), targetsAt({target}, {Eigen::Vector3d::Zero()}), target, p, rng2);
  int behind = 0;
  for (const auto& v : any.roi) behind += (v.origin - target).dot(facing) < 0.0 ? 1 : 0;
  EXPECT_GT(behind, 25);
  EXPECT_LT(behind, 75);
}

TEST(UpstreamSampling, PredictedSurfaceAViewSeesAddsItsGainToTheUtilityUnlessTheMapHidesIt) {
  // The integration patch adds shapeViewGain to each ROI candidate's utility: every view of the
  // lone target faces it from 0.3-0.5 m, so each gains the target's 0.4, until a wall of
  // occupied cells stands around it.
  RoiOcTree tree(kRes);
  setFree(&tree, 0, 0, 0);
  const Eigen::Vector3d target(0.305, 0.205, 0.505);
  const ShapeTargets t = loneTargetWithGain(target, 0.0);
  const SampledCandidates s = sampleRoiOnly(tree, t, target);
  ASSERT_EQ(s.roi.size(), 100u);
  for (const auto& v : s.roi) {
    EXPECT_DOUBLE_EQ(v.shape_gain, 0.4);
    EXPECT_NEAR(v.utility, v.gain - 0.2 * (v.origin - target).norm() + 0.4, 1e-12);
  }
  // Occupied cells 2-3 cm around the target on the side it faces: no view sees it.
  for (int x = 25; x <= 35; ++x)
    for (int z = 45; z <= 55; ++z)
      for (int y = 22; y <= 23; ++y) setOccupied(&tree, x, y, z);
  for (int x = 25; x <= 35; ++x)
    for (int y = 19; y <= 23; ++y) setOccupied(&tree, x, y, 55), setOccupied(&tree, x, y, 45);
  for (int z = 45; z <= 55; ++z)
    for (int y = 19; y <= 23; ++y) setOccupied(&tree, 25, y, z), setOccupied(&tree, 35, y, z);
  const SampledCandidates hidden = sampleRoiOnly(tree, t, target);
  ASSERT_FALSE(hidden.roi.empty());
  for (const auto& v : hidden.roi) EXPECT_EQ(v.shape_gain, 0.0);
}

TEST(UpstreamSampling, AViewAmongTheMappedPlantKeepsItsOwnUtilityButGainsNothingFromPredictedSurface) {
  // One occupied cell 40 cm out on the side the target faces: views sampled within the 15 cm
  // clearance of it gain nothing from the target, the others its 0.4; all keep upstream's utility.
  RoiOcTree tree(kRes);
  setFree(&tree, 0, 0, 0);
  setOccupied(&tree, 30, 60, 50);  // the cell [0.30, 0.31] x [0.60, 0.61] x [0.50, 0.51]
  const Eigen::Vector3d target(0.305, 0.205, 0.505);
  const SampledCandidates s = sampleRoiOnly(tree, loneTargetWithGain(target, 0.15), target);
  ASSERT_EQ(s.roi.size(), 100u);
  const Eigen::Vector3d cell_min(0.30, 0.60, 0.50), cell_max(0.31, 0.61, 0.51);
  int crowded = 0, clear = 0;
  for (const auto& v : s.roi) {
    const double to_cell = (v.origin.cwiseMax(cell_min).cwiseMin(cell_max) - v.origin).norm();
    if (std::abs(to_cell - 0.15) < 1e-3) continue;  // float rounding at the boundary
    const bool near = to_cell < 0.15;
    (near ? crowded : clear) += 1;
    EXPECT_DOUBLE_EQ(v.shape_gain, near ? 0.0 : 0.4) << "camera " << to_cell << " m from the cell";
    EXPECT_NEAR(v.utility, v.gain - 0.2 * (v.origin - target).norm() + v.shape_gain, 1e-12);
  }
  EXPECT_GT(crowded, 5);
  EXPECT_GT(clear, 5);
}
