#include <fruit_shape_completion/SuperellipsoidArray.h>
#include <fruit_shape_completion/sim/analytic_depth_camera.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/shape_estimator_loader.h>
#include <fruit_shape_completion/sim/fruit_truth.h>
#include <fruit_shape_completion/sim/procedural_scene.h>
#include <fruit_shape_completion/sim/synthetic_fruit.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <limits>

using namespace fruit_shape_completion;

namespace {

// Waits (spinning) until pred() or the timeout; true if pred() held.
template <typename Pred>
bool waitFor(Pred pred, double seconds) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < end) {
    ros::spinOnce();
    if (pred()) return true;
    ros::WallDuration(0.05).sleep();
  }
  return pred();
}

}  // namespace

TEST(Plugin, LoadsByNameThroughPluginlib) {
  pluginlib::ClassLoader<ShapeEstimatorPlugin> loader("fruit_shape_completion", "fruit_shape_completion::ShapeEstimatorPlugin");
  const auto classes = loader.getDeclaredClasses();
  ASSERT_NE(std::find(classes.begin(), classes.end(), "fruit_shape_completion/SuperellipsoidEstimator"), classes.end());
  std::unique_ptr<ShapeEstimatorPlugin> plugin(loader.createUnmanagedInstance("fruit_shape_completion/SuperellipsoidEstimator"));
  ros::NodeHandle nh("~/plugin_test");
  plugin->initialize("plugin_test", nh, "world");
  EXPECT_EQ(plugin->name(), "plugin_test");
  // It works: a half-seen fruit in, a fit out.
  std::mt19937 rng(4);
  const Superellipsoid truth = randomSuperellipsoid(rng, Eigen::Vector3d(0, 0.5, 0.5));
  ScanParams scan;
  scan.view_dir = Eigen::Vector3d(0, -1, 0);
  scan.visible_fraction = 0.6;
  scan.voxel = 0.002;
  const PointList fruit = scanFruit(SyntheticFruit::fromSuperellipsoid(truth), scan), none;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(0, 0.1, 0.5);
  pose.linear() = PinholeCamera::lookingAt(pose.translation(), truth.t).rotation;
  plugin->insertView(planner::ViewData{fruit, none, pose, 0.0});
  plugin->update();
  ASSERT_EQ(plugin->fruits().size(), 1u);
  EXPECT_NEAR(plugin->fruits()[0].volume, truth.volume(), 0.1 * truth.volume());
  plugin.reset();
}

TEST(Plugin, WrongNameOrBadParameterFailsAtStartWithAMessage) {
  ros::NodeHandle nh("~/bad_name");
  XmlRpc::XmlRpcValue list;
  list[0]["name"] = "shape";
  list[0]["type"] = "fruit_shape_completion/NoSuchEstimator";
  nh.setParam("shape_estimators", list);
  ros_io::ShapeEstimatorLoader loader;
  try {
    loader.load(nh, "world");
    FAIL() << "an unknown plugin type must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("NoSuchEstimator"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("SuperellipsoidEstimator"), std::string::npos) << e.what();  // known types listed
  }
  ros::NodeHandle bad("~/bad_param");
  list[0]["type"] = "fruit_shape_completion/SuperellipsoidEstimator";
  bad.setParam("shape_estimators", list);
  bad.setParam("shape/alpha", -1.0);
  try {
    loader.load(bad, "world");
    FAIL() << "a bad parameter must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("alpha"), std::string::npos) << e.what();
  }
  bad.setParam("shape/alpha", "not a number");
  EXPECT_THROW(loader.load(bad, "world"), std::runtime_error);
}

TEST(FruitPublisher, CloudsRoundTripAndLyingHeadersAreRefused) {
  const PointList pts = {Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(-1, 2, -3)};
  const sensor_msgs::PointCloud2 good = ros_io::toCloud(pts, "world", ros::Time(0));
  PointList back;
  std::size_t non_finite = 0;
  std::string err;
  ASSERT_TRUE(ros_io::fromCloud(good, &back, &non_finite, &err)) << err;
  ASSERT_EQ(back.size(), 2u);
  EXPECT_LT((back[1] - pts[1]).norm(), 1e-6);
  // width * point_step wraps around 32 bits: must not pass the size check.
  sensor_msgs::PointCloud2 wrap = good;
  wrap.width = 0x40000000u;
  wrap.height = 1;
  wrap.point_step = 16;
  wrap.row_step = 0;  // what 0x40000000 * 16 is in 32-bit arithmetic
  EXPECT_FALSE(ros_io::fromCloud(wrap, &back, &non_finite, &err));
  EXPECT_FALSE(err.empty());
  sensor_msgs::PointCloud2 tall = good;
  tall.height = 0x10000u;
  tall.row_step = 0x10000u;  // row_step * height wraps to 0 in 32 bits
  EXPECT_FALSE(ros_io::fromCloud(tall, &back, &non_finite, &err));
  sensor_msgs::PointCloud2 big_endian = good;
  big_endian.is_bigendian = true;
  EXPECT_FALSE(ros_io::fromCloud(big_endian, &back, &non_finite, &err));
  EXPECT_NE(err.find("big-endian"), std::string::npos) << err;
}

TEST(SurfaceCloudNode, SkipsBadCloudsAndFitsGoodOnes) {
  ros::NodeHandle nh;
  ros::Publisher pub = nh.advertise<sensor_msgs::PointCloud2>("/surface_cloud_node/surface_cloud", 1, true);
  fruit_shape_completion::SuperellipsoidArray last;
  int received = 0;
  ros::Subscriber sub = nh.subscribe<fruit_shape_completion::SuperellipsoidArray>(
      "/surface_cloud_node/superellipsoids", 5, [&](const fruit_shape_completion::SuperellipsoidArrayConstPtr& m) {
        last = *m;
        ++received;
      });
  ASSERT_TRUE(waitFor([&] { return pub.getNumSubscribers() > 0; }, 20.0));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  pub.publish(ros_io::toCloud(PointList(500, Eigen::Vector3d(nan, nan, nan)), "world", ros::Time::now()));
  pub.publish(ros_io::toCloud(PointList(), "world", ros::Time::now()));
  ros::WallDuration(0.5).sleep();
  std::mt19937 rng(9);
  const Superellipsoid truth = randomSuperellipsoid(rng, Eigen::Vector3d(0.2, 0.6, 0.4));
  ScanParams scan;
  scan.visible_fraction = 0.7;
  pub.publish(ros_io::toCloud(scanFruit(SyntheticFruit::fromSuperellipsoid(truth), scan), "world", ros::Time::now()));
  ASSERT_TRUE(waitFor([&] { return received > 0 && last.superellipsoids.size() == 1; }, 20.0));
  EXPECT_NEAR(last.superellipsoids[0].volume, truth.volume(), 0.05 * truth.volume());
  EXPECT_NEAR(last.superellipsoids[0].tx, truth.t.x(), 0.004);
  EXPECT_EQ(last.header.frame_id, "world");
}

TEST(PlannerNode, HeadlessEpisodePublishesFruitsMatchingTheTruth) {
  ros::NodeHandle nh;
  fruit_shape_completion::SuperellipsoidArray last;
  std::size_t markers = 0;
  ros::Subscriber sub = nh.subscribe<fruit_shape_completion::SuperellipsoidArray>(
      "/roi_viewpoint_planner/superellipsoid/superellipsoids", 5,
      [&](const fruit_shape_completion::SuperellipsoidArrayConstPtr& m) { last = *m; });
  ros::Subscriber msub = nh.subscribe<visualization_msgs::MarkerArray>(
      "/roi_viewpoint_planner/superellipsoid/fruit_markers", 5,
      [&](const visualization_msgs::MarkerArrayConstPtr& m) { markers = m->markers.size(); });
  sim::Scene scene;
  std::string err;
  ASSERT_TRUE(sim::loadSceneSpec("procedural:3", &scene, &err));
  int red = 0;
  const auto truth = sim::computeFruitTruth(scene);
  for (const auto& f : truth) red += f.color == "red";
  ASSERT_TRUE(waitFor([&] { return static_cast<int>(last.superellipsoids.size()) >= red / 2; }, 180.0))
      << "only " << last.superellipsoids.size() << " superellipsoids published for " << red << " red fruits";
  EXPECT_GT(markers, last.superellipsoids.size());  // a mesh and a label per fruit
  int good = 0;
  for (const auto& s : last.superellipsoids) {
    double best = 1e9, acc = -1;
    for (const auto& f : truth) {
      const double d = (f.center - Eigen::Vector3d(s.tx, s.ty, s.tz)).norm();
      if (d < best) {
        best = d;
        acc = 1 - std::abs(s.volume - f.volume) / f.volume;
      }
    }
    good += best < 0.02 && acc > 0.8;
  }
  EXPECT_GE(good, static_cast<int>(0.8 * last.superellipsoids.size()));
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_ros_integration");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
