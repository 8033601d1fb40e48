#include <fruit_shape_completion/instrument/sim/robot_arm.h>
#include <fruit_shape_completion/instrument/sim/scene.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <random>

using namespace fruit_shape_completion;
using namespace fruit_shape_completion::sim;

namespace {

// A wall of two triangles at y = wall_y spanning x, z in [-1, 2].
void addWall(Scene& s, float wall_y) {
  const int b = static_cast<int>(s.vertices.size());
  s.vertices.emplace_back(-1.f, wall_y, -1.f);
  s.vertices.emplace_back(2.f, wall_y, -1.f);
  s.vertices.emplace_back(2.f, wall_y, 2.f);
  s.vertices.emplace_back(-1.f, wall_y, 2.f);
  s.triangles.emplace_back(b, b + 1, b + 2);
  s.triangles.emplace_back(b, b + 2, b + 3);
  s.triangle_material.insert(s.triangle_material.end(), 2, 0);
  s.triangle_plant.insert(s.triangle_plant.end(), 2, 0);
}

Scene poleScene() {
  Scene s;
  s.materials = {{"leaf", {{40, 100, 30}}, false}};
  s.robot.kind = RobotMount::Kind::kPole;
  s.robot.base = Eigen::Vector3d(0, 0, 0.86);
  return s;
}

JointVector randomJoints(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-M_PI, M_PI);
  JointVector q;
  for (int i = 0; i < 6; ++i) q[i] = u(rng);
  return q;
}

double angleGap(double a, double b) { return std::abs(std::remainder(a - b, 2 * M_PI)); }

}  // namespace

TEST(Ur5eKinematics, ZeroPoseIsThePublishedOne) {
  // With every joint at 0 the flange sits at (a2 + a3, -(d4 + d6), d1 - d5).
  const Eigen::Vector3d p = ur5e::flangePose(JointVector::Zero()).translation();
  EXPECT_NEAR(p.x(), -0.8172, 1e-9);
  EXPECT_NEAR(p.y(), -0.2329, 1e-9);
  EXPECT_NEAR(p.z(), 0.0628, 1e-9);
}

TEST(Ur5eKinematics, InverseRecoversEveryPoseAndTheJointsThatMadeIt) {
  std::mt19937 rng(7);
  int found_original = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const JointVector q = randomJoints(rng);
    const Eigen::Isometry3d pose = ur5e::flangePose(q);
    const auto solutions = ur5e::inverse(pose, q[5]);
    ASSERT_FALSE(solutions.empty()) << "trial " << trial;
    ASSERT_LE(solutions.size(), 8u);
    bool original = false;
    for (const JointVector& s : solutions) {
      const Eigen::Isometry3d back = ur5e::flangePose(s);
      EXPECT_LT((back.translation() - pose.translation()).norm(), 1e-9);
      EXPECT_LT((back.linear() - pose.linear()).norm(), 1e-9);
      double gap = 0;
      for (int i = 0; i < 6; ++i) gap = std::max(gap, angleGap(s[i], q[i]));
      original = original || gap < 1e-6;
    }
    found_original += original;
  }
  EXPECT_EQ(found_original, 500);
  // Beyond the arm's reach (0.85 m): no solution.
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(1.0, 0.2, 0.3);
  EXPECT_TRUE(ur5e::inverse(far).empty());
}

TEST(Ur5eKinematics, JointLimitsAndNearestEquivalentAngles) {
  JointVector q = JointVector::Zero(), ref = JointVector::Zero(), out;
  ref[0] = 5.5;   // near +2 pi: the equivalent of 0 nearest it is 2 pi
  q[2] = 3.0;     // elbow within +-pi
  ASSERT_TRUE(ur5e::nearestWithinLimits(q, ref, &out));
  EXPECT_NEAR(out[0], 2 * M_PI, 1e-12);
  EXPECT_NEAR(out[2], 3.0, 1e-12);
  EXPECT_TRUE(ur5e::withinLimits(out));
  out[2] = 3.3;
  EXPECT_FALSE(ur5e::withinLimits(out));
}

TEST(Ur5eKinematics, SegmentDistances) {
  const Eigen::Vector3d o = Eigen::Vector3d::Zero();
  EXPECT_NEAR(segmentDistance(o, {1, 0, 0}, {0.5, -1, 0.3}, {0.5, 1, 0.3}), 0.3, 1e-12);  // crossing above
  EXPECT_NEAR(segmentDistance(o, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}), 1.0, 1e-12);            // collinear, apart
  EXPECT_NEAR(segmentDistance(o, {1, 0, 0}, {0.2, 0.5, 0}, {0.8, 0.5, 0}), 0.5, 1e-12);    // parallel
  EXPECT_NEAR(segmentDistance(o, o, {1, 1, 0}, {1, 1, 0}), std::sqrt(2.0), 1e-12);         // two points
}

TEST(RobotArm, ReachesAViewInFrontAndPlacesTheCameraExactly) {
  const Scene scene = poleScene();
  const RobotArm arm(scene);
  ArmState from;
  from.base = scene.robot.base;
  from.q << 0, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0;
  const PinholeCamera cam = PinholeCamera::lookingAt({0.1, 0.45, 0.8}, {0.1, 0.9, 0.6});
  ArmState to;
  ASSERT_EQ(arm.reach(cam, from, ArmMotion(), arm.plants(), &to), RobotArm::Reach::kReached);
  const Eigen::Isometry3d got = arm.cameraPose(to);
  EXPECT_LT((got.translation() - cam.position).norm(), 1e-9);
  EXPECT_LT((got.linear() - cam.rotation).norm(), 1e-9);
  EXPECT_TRUE(ur5e::withinLimits(to.q));
  EXPECT_FALSE(arm.collides(to, arm.plants()));
  // 1.2 m from the shoulder: beyond the UR5e's 0.85 m.
  const PinholeCamera far = PinholeCamera::lookingAt({0.0, 1.2, 1.0}, {0.0, 1.6, 0.8});
  EXPECT_EQ(arm.reach(far, from, ArmMotion(), arm.plants(), &to), RobotArm::Reach::kNoInverse);
  // Under the base, where only the pole is: every solution folds the arm into it or itself.
  const PinholeCamera under = PinholeCamera::lookingAt({0.0, 0.05, 0.45}, {0.0, 0.4, 0.45});
  EXPECT_NE(arm.reach(under, from, ArmMotion(), arm.plants(), &to), RobotArm::Reach::kReached);
}

TEST(RobotArm, PlantsBlockTheViewsWhoseLinksWouldPassThroughThem) {
  Scene scene = poleScene();
  addWall(scene, 0.5f);
  const RobotArm arm(scene);
  EXPECT_NEAR(arm.plants().at({0.3, 0.3, 0.8}), 0.2, 0.011);
  EXPECT_NEAR(arm.plants().at({0.3, 0.5, 0.8}), 0.0, 0.011);
  ArmState from;
  from.base = scene.robot.base;
  from.q << 0, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0;
  ArmState to;
  // In front of the wall: fine. Behind it: the forearm would cross the wall.
  EXPECT_EQ(arm.reach(PinholeCamera::lookingAt({0.0, 0.3, 0.9}, {0.0, 0.45, 0.8}), from, ArmMotion(), arm.plants(), &to),
            RobotArm::Reach::kReached);
  const PinholeCamera behind = PinholeCamera::lookingAt({0.0, 0.62, 0.9}, {0.0, 0.9, 0.8});
  EXPECT_EQ(arm.reach(behind, from, ArmMotion(), arm.plants(), &to), RobotArm::Reach::kCollision);
  // A planner that has not seen the wall plans through it; one whose map holds the wall's
  // points (2 cm cells) does not.
  EXPECT_EQ(arm.reach(behind, from, ArmMotion(), DistanceField(), &to), RobotArm::Reach::kReached);
  EXPECT_TRUE(arm.collides(to, arm.plants()));
  PointList seen;
  for (double x = -0.6; x <= 0.6; x += 0.01)
    for (double z = 0.3; z <= 1.5; z += 0.01) seen.emplace_back(x, 0.5, z);
  const DistanceField map = DistanceField::ofPoints(seen, 0.02, 0.2);
  EXPECT_NEAR(map.at({0.0, 0.3, 0.9}), 0.2, 0.021);
  EXPECT_EQ(arm.reach(behind, from, ArmMotion(), map, &to), RobotArm::Reach::kCollision);
  EXPECT_TRUE(DistanceField::ofPoints({}, 0.02, 0.2).empty());
}

TEST(RobotArm, MotionTimeIsTrapezoidalAtTheScaledLimits) {
  const RobotArm arm(poleScene());
  ArmMotion m;  // 0.5 x (pi rad/s, 3.14 rad/s^2)
  ArmState a, b;
  b.q[0] = M_PI;
  // Cruise at pi/2 rad/s after 1 s of acceleration: 2 s + 1 s.
  const double v = 0.5 * ur5e::kMaxVelocity;
  EXPECT_NEAR(arm.motionTime(a, b, m), M_PI / v + v / (0.5 * 3.14), 1e-9);
  b.q[0] = 0.1;  // too short to reach cruise speed: 2 sqrt(d / a)
  EXPECT_NEAR(arm.motionTime(a, b, m), 2 * std::sqrt(0.1 / 1.57), 1e-9);
  b.q[3] = -1.0;  // the slowest axis decides
  EXPECT_GT(arm.motionTime(a, b, m), 1.0);
  m.velocity_scaling = 1.0;
  m.acceleration_scaling = 1.0;
  EXPECT_LT(arm.motionTime(a, b, m), arm.motionTime(a, b, ArmMotion()));
  m.velocity_scaling = 0.0;
  EXPECT_FALSE(m.problem().empty());
}

TEST(RobotArm, GantryMovesTheBaseToReachFarViews) {
  Scene scene;
  scene.materials = {{"leaf", {{40, 100, 30}}, false}};
  scene.robot.kind = RobotMount::Kind::kGantry;
  const RobotArm arm(scene);
  ArmState from;
  from.base = Eigen::Vector3d(-1, -1, 1.69);
  from.q << 0, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0;
  ArmState to;
  const PinholeCamera cam = PinholeCamera::lookingAt({0.8, 0.7, 0.7}, {0.8, 1.2, 0.5});
  ASSERT_EQ(arm.reach(cam, from, ArmMotion(), arm.plants(), &to), RobotArm::Reach::kReached);
  EXPECT_LT((arm.cameraPose(to).translation() - cam.position).norm(), 1e-9);
  EXPECT_GT((to.base - from.base).norm(), 1.0);  // the gantry carried it
  EXPECT_LE(to.base.head<2>().maxCoeff(), 1.0 + 1e-12);
  EXPECT_GE(to.base.z(), 1.69 - 0.5 - 1e-12);
  // Hanging arm: the base is above the camera.
  EXPECT_GT(to.base.z(), cam.position.z());
  // Far below the lowest base (1.19 m) by more than the arm's reach.
  EXPECT_EQ(arm.reach(PinholeCamera::lookingAt({0.0, 0.0, 0.1}, {0.0, 0.5, 0.0}), from, ArmMotion(), arm.plants(), &to),
            RobotArm::Reach::kNoInverse);
}

TEST(RobotArm, SceneFilesSayTheMount) {
  const std::string dir = ::testing::TempDir();
  auto write = [&](const std::string& robot) {
    std::ofstream(dir + "/fsc_arm.obj") << "mtllib fsc_arm.mtl\nv 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nusemtl leaf\nf 1 2 3\n";
    std::ofstream(dir + "/fsc_arm.mtl") << "newmtl leaf\nmap_Kd fsc_leaf.png\n";
    std::ofstream(dir + "/fsc_leaf.png") << "\x89PNG not really";
    std::ofstream f(dir + "/fsc_arm.yaml");
    f << "plants:\n  - {mesh: fsc_arm.obj, position: [0, 0.5, 0]}\nmaterials:\n  leaf: {rgb: [40, 100, 30]}\n" << robot;
  };
  Scene s;
  std::string err;
  write("robot: {arm: ur5e, mount: gantry, xy_min: [-0.5, -1], xy_max: [1, 0.5], top: 2.0, max_drop: 0.3}\n");
  ASSERT_TRUE(loadScene(dir + "/fsc_arm.yaml", &s, &err)) << err;
  EXPECT_EQ(s.robot.kind, RobotMount::Kind::kGantry);
  EXPECT_DOUBLE_EQ(s.robot.top, 2.0);
  EXPECT_DOUBLE_EQ(s.robot.xy_min.x(), -0.5);
  EXPECT_FALSE(s.robot.inferred);
  // A texture in a format the simulator does not read: a note, and the flat colour.
  ASSERT_EQ(s.notes.size(), 1u);
  EXPECT_NE(s.notes[0].find("not a TGA"), std::string::npos) << s.notes[0];
  EXPECT_FALSE(s.materials[0].texture);
  write("robot: {arm: ur5e, mount: pole, base: [0.1, 0, 0.7]}\n");
  ASSERT_TRUE(loadScene(dir + "/fsc_arm.yaml", &s, &err)) << err;
  EXPECT_EQ(s.robot.kind, RobotMount::Kind::kPole);
  EXPECT_DOUBLE_EQ(s.robot.base.z(), 0.7);
  write("workspace: {box_min: [-1, -1, 0], box_max: [1, 1, 2], reach_center: [0, 0, 0.86], reach_radius: 0.85}\n");
  ASSERT_TRUE(loadScene(dir + "/fsc_arm.yaml", &s, &err)) << err;
  EXPECT_EQ(s.robot.kind, RobotMount::Kind::kPole);
  EXPECT_TRUE(s.robot.inferred);
  EXPECT_NE(s.robot.describe().find("inferred"), std::string::npos);
  for (const char* bad : {"robot: {mount: crane}\n", "robot: {mount: gantry, xy_min: [0, 0], xy_max: [-1, 1], top: 2, max_drop: 0.1}\n",
                          "robot: {mount: pole, base: [0, .nan, 1]}\n", "robot: {arm: ur10, mount: pole, base: [0, 0, 1]}\n",
                          "robot: {mount: pole, base: [0, 0, 1], pole_radius: -0.05}\n"}) {
    write(bad);
    err.clear();
    EXPECT_FALSE(loadScene(dir + "/fsc_arm.yaml", &s, &err)) << bad;
    EXPECT_NE(err.find("robot"), std::string::npos) << err;
  }
}
