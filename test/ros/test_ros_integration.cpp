#include <diagnostic_msgs/DiagnosticArray.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <sensor_msgs/Image.h>
#include <fruit_shape_completion/FilePath.h>
#include <superellipsoid_msgs/SuperellipsoidArray.h>
#include <std_srvs/Empty.h>
#include <unistd.h>
#include <fruit_shape_completion/instrument/sim/analytic_depth_camera.h>
#include <fruit_shape_completion/ros/camera_frames.h>
#include <fruit_shape_completion/ros/estimator_params.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/roi_planner_shape_estimators.h>
#include <fruit_shape_completion/ros/shape_estimator_loader.h>
#include <fruit_shape_completion/ros/upstream_messages.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>
#include <fruit_shape_completion/instrument/sim/rgbd_renderer.h>
#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>
#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include "wait_for.h"
#include <ros/ros.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl_conversions/pcl_conversions.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <topic_tools/shape_shifter.h>
#include <visualization_msgs/MarkerArray.h>

#include <cstdio>
#include <cstdlib>
#include <future>
#include <sstream>
#include <fstream>
#include <atomic>
#include <limits>

using namespace fruit_shape_completion;

namespace {

// Waits (spinning) until pred() or the timeout; true if pred() held.
using test::waitFor;

// A received message's bytes read as a superellipsoid_msgs subscriber reads them.
superellipsoid_msgs::SuperellipsoidArray asSuperellipsoidArray(const topic_tools::ShapeShifter& msg) {
  std::vector<std::uint8_t> bytes(msg.size());
  ros::serialization::OStream out(bytes.data(), bytes.size());
  msg.write(out);
  ros::serialization::IStream in(bytes.data(), bytes.size());
  superellipsoid_msgs::SuperellipsoidArray arr;
  ros::serialization::deserialize(in, arr);
  return arr;
}

// A PointcloudWithRoi as pointcloud_roi builds it: the camera's coloured cloud in the map frame,
// voxel-downsampled to 1 cm, the indices of its red points, the camera pose as the transform.
// `in_camera_frame` instead keeps the cloud in the camera frame (the transform then takes it to
// the map), the other case upstream's planner handles.
pointcloud_roi_msgs::PointcloudWithRoi roiCloud(const AnalyticScene& scene, std::size_t fruit_shapes,
                                                   const PinholeCamera& camera, bool in_camera_frame = false) {
  const DepthScan scan = renderDepth(scene, camera, 0.0005, 3);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = camera.rotation;
  pose.translation() = camera.position;
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr full(new pcl::PointCloud<pcl::PointXYZRGB>);
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    const Eigen::Vector3d p = in_camera_frame ? Eigen::Vector3d(pose.inverse() * scan.points[i]) : scan.points[i];
    pcl::PointXYZRGB q;
    q.x = p.x(), q.y = p.y(), q.z = p.z();
    const bool fruit = static_cast<std::size_t>(scan.labels[i]) < fruit_shapes;
    q.r = fruit ? 200 : 40, q.g = fruit ? 20 : 160, q.b = 30;
    full->push_back(q);
  }
  pcl::PointCloud<pcl::PointXYZRGB> down;
  pcl::VoxelGrid<pcl::PointXYZRGB> grid;
  grid.setInputCloud(full);
  grid.setLeafSize(0.01f, 0.01f, 0.01f);
  grid.filter(down);
  pointcloud_roi_msgs::PointcloudWithRoi msg;
  for (std::size_t i = 0; i < down.size(); ++i)
    if (down[i].r > down[i].g) msg.roi_indices.push_back(static_cast<std::int32_t>(i));  // the red test
  pcl::toROSMsg(down, msg.cloud);
  msg.cloud.header.frame_id = in_camera_frame ? "camera" : "world";
  msg.transform = tf2::eigenToTransform(pose).transform;
  return msg;
}

// A fruit on a leaf and cameras around its front, 35-45 cm away.
struct FruitOnALeaf {
  AnalyticScene scene;
  Superellipsoid truth;
  std::vector<PinholeCamera> cameras;
  FruitOnALeaf() {
    truth.a = 0.04, truth.b = 0.035, truth.c = 0.05, truth.e1 = 0.7, truth.e2 = 0.8;
    truth.t = Eigen::Vector3d(0.3, 0.6, 0.8);
    truth.rpy = Eigen::Vector3d(0.1, -0.2, 0.4);
    scene.shapes.push_back(truth);
    scene.planes.push_back({Eigen::Vector3d(0.3, 0.72, 0.8), Eigen::Vector3d(0, 1, 0)});
    for (double az : {-0.7, -0.25, 0.2, 0.6})
      for (double el : {-0.3, 0.35}) {
        const Eigen::Vector3d dir(std::sin(az) * std::cos(el), -std::cos(az) * std::cos(el), std::sin(el));
        cameras.push_back(PinholeCamera::lookingAt(truth.t + 0.4 * dir, truth.t));
      }
  }
};

// What depth_image_proc publishes for a camera over an analytic scene: organized, in the camera
// frame, shape 0 red and the rest green.
OrganizedFrame organizedRender(const AnalyticScene& scene, const PinholeCamera& cam) {
  OrganizedFrame f;
  f.width = cam.width;
  f.height = cam.height;
  f.xyz.assign(3 * f.pixels(), std::numeric_limits<float>::quiet_NaN());
  f.rgb.assign(3 * f.pixels(), 0);
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      const Eigen::Vector3d dir = cam.rayDirection(u, v);
      double t = 0;
      const int hit = scene.intersect(cam.position, dir, cam.min_range, cam.max_range, &t);
      if (hit < 0) continue;
      const std::size_t px = static_cast<std::size_t>(v) * cam.width + u;
      const Eigen::Vector3d p = cam.rotation.transpose() * (t * dir);
      for (int k = 0; k < 3; ++k) f.xyz[3 * px + k] = static_cast<float>(p[k]);
      const std::uint8_t red[3] = {190, 25, 20}, green[3] = {40, 150, 35};
      for (int k = 0; k < 3; ++k) f.rgb[3 * px + k] = hit == 0 ? red[k] : green[k];
    }
  return f;
}

// A diagnostics entry of the plugin as a number (a failure if it has none).
std::size_t diagnosticCount(const ShapeEstimatorPlugin& plugin, const std::string& key) {
  for (const auto& kv : plugin.diagnostics())
    if (kv.first == key) return std::stoul(kv.second);
  ADD_FAILURE() << "no diagnostics entry '" << key << "'";
  return 0;
}

// `~shape_estimators` under nh, as the planner's launch file sets it: one estimator.
void setOneEstimator(const ros::NodeHandle& nh, const std::string& name, const std::string& type) {
  XmlRpc::XmlRpcValue list;
  list[0]["name"] = name;
  list[0]["type"] = type;
  nh.setParam("shape_estimators", list);
}

// A random fruit 60 % seen by one camera 40 cm from it (2 mm voxels).
struct HalfSeenFruit {
  Superellipsoid truth;
  PointList fruit;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  HalfSeenFruit() {
    std::mt19937 rng(4);
    truth = randomSuperellipsoid(rng, Eigen::Vector3d(0, 0.5, 0.5));
    ScanParams scan;
    scan.view_dir = Eigen::Vector3d(0, -1, 0);
    scan.visible_fraction = 0.6;
    scan.voxel = 0.002;
    fruit = scanFruit(SyntheticFruit::fromSuperellipsoid(truth), scan);
    pose.translation() = Eigen::Vector3d(0, 0.1, 0.5);
    pose.linear() = PinholeCamera::lookingAt(pose.translation(), truth.t).rotation;
  }
};

// A SuperellipsoidEstimator plugin in ~/<name> fed by the camera clouds on <name>_points.
std::unique_ptr<ShapeEstimatorPlugin> cameraPlugin(pluginlib::ClassLoader<ShapeEstimatorPlugin>& loader,
                                                   const std::string& name, ros::NodeHandle* nh) {
  std::unique_ptr<ShapeEstimatorPlugin> plugin(loader.createUnmanagedInstance("fruit_shape_completion/SuperellipsoidEstimator"));
  *nh = ros::NodeHandle("~/" + name);
  nh->setParam("superellipsoids_topic", "superellipsoids");
  nh->setParam("camera_cloud_topic", name + "_points");
  plugin->initialize(name, *nh, "world");
  return plugin;
}

// The scene's camera poses as static tf frames <prefix>0, <prefix>1, ... in "world".
std::vector<geometry_msgs::TransformStamped> sendCameraPoses(const FruitOnALeaf& s, const std::string& prefix,
                                                             tf2_ros::StaticTransformBroadcaster* tf) {
  std::vector<geometry_msgs::TransformStamped> poses;
  for (std::size_t i = 0; i < s.cameras.size(); ++i) {
    geometry_msgs::TransformStamped t = tf2::eigenToTransform(sim::cameraPose(s.cameras[i]));
    t.header.frame_id = "world";
    t.child_frame_id = prefix + std::to_string(i);
    poses.push_back(t);
  }
  tf->sendTransform(poses);
  return poses;
}

}  // namespace

TEST(RoiPlannerShapeEstimators, PointcloudRoiViewsGiveTheFruitAndTargetsOnItsUnseenSide) {
  ros::NodeHandle nh("~/glue");
  setOneEstimator(nh, "superellipsoid", "fruit_shape_completion/SuperellipsoidEstimator");
  nh.setParam("superellipsoid/superellipsoids_topic", "superellipsoids");
  ros_io::RoiPlannerShapeEstimators estimators(nh, "world");
  const FruitOnALeaf s;
  for (std::size_t i = 0; i < s.cameras.size(); ++i) {
    const auto msg = roiCloud(s.scene, 1, s.cameras[i], i % 2 == 1);
    ASSERT_GT(msg.roi_indices.size(), 50u);
    estimators.insertView(msg.cloud, msg.roi_indices, msg.transform, i);
  }
  EXPECT_EQ(estimators.viewsSkipped(), 0u);
  const auto fruits = estimators.host().fruits(0);
  ASSERT_EQ(fruits.size(), 1u);
  EXPECT_LT((fruits[0].center() - s.truth.t).norm(), 0.01);
  EXPECT_NEAR(fruits[0].volume, s.truth.volume(), 0.25 * s.truth.volume());
  const auto targets = estimators.extraTargets();
  ASSERT_GT(targets.size(), 10u);
  int behind = 0;
  for (const auto& p : targets) {
    const Eigen::Vector3d q(p.x(), p.y(), p.z());
    behind += (q - s.truth.t).y() > 0;  // the cameras are all at y < fruit
  }
  EXPECT_GT(behind, static_cast<int>(0.8 * targets.size()));
  // What the patched sampler adds to a view's utility (target_view_gain 1 by default): the
  // unseen side seen from behind gains a good share of a fruit; from the cameras' side, nothing.
  const ros_io::ShapeTargetRound round = estimators.targetRound();
  ASSERT_EQ(round.points.size(), targets.size());
  const octomap::OcTree nothing_in_the_way(0.01);
  auto at = [&](double dy) {
    return octomap::point3d(static_cast<float>(s.truth.t.x()), static_cast<float>(s.truth.t.y() + dy),
                            static_cast<float>(s.truth.t.z()));
  };
  EXPECT_GT(round.viewGain(at(0.4), octomap::point3d(0, -1, 0), nothing_in_the_way), 0.2);
  EXPECT_EQ(round.viewGain(at(-0.4), octomap::point3d(0, 1, 0), nothing_in_the_way), 0.0);
  // Bad input is skipped and counted, not fatal, and the fruit stays.
  auto bad = roiCloud(s.scene, 1, s.cameras[0]);
  bad.roi_indices.push_back(-5);
  bad.roi_indices.push_back(1 << 30);
  estimators.insertView(bad.cloud, bad.roi_indices, bad.transform);
  EXPECT_EQ(estimators.indicesSkipped(), 2u);
  bad.cloud.data.resize(10);
  estimators.insertView(bad.cloud, bad.roi_indices, bad.transform);
  EXPECT_EQ(estimators.viewsSkipped(), 1u);
  EXPECT_EQ(estimators.host().fruits(0).size(), 1u);
  // ... and a user sees both counts in /diagnostics, in this process's input status.
  std::string views_value, indices_value;
  const std::string status_name = ros::this_node::getName().substr(1) + ": shape estimators: PointcloudWithRoi input";
  ros::Subscriber diag = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& a) {
        for (const auto& st : a->status) {
          if (st.name != status_name) continue;
          for (const auto& kv : st.values) {
            if (kv.key.rfind("views skipped", 0) == 0 && kv.value != "0") views_value = kv.value;
            if (kv.key.rfind("ROI indices skipped", 0) == 0 && kv.value != "0") indices_value = kv.value;
          }
        }
      });
  EXPECT_TRUE(waitFor([&] { return !views_value.empty() && !indices_value.empty(); }, 10.0));
  EXPECT_EQ(views_value, "1");
  EXPECT_EQ(indices_value, "2");
  // The patched planner reads resets() when its tree takes a view; a reset between that and the
  // hand-over (its callback and its planning thread race) leaves the view out of the new map.
  const std::uint64_t ticket = estimators.resets();
  estimators.reset();
  EXPECT_EQ(estimators.resets(), ticket + 1);
  EXPECT_EQ(estimators.viewsSkipped(), 0u);
  EXPECT_TRUE(estimators.host().fruits(0).empty());
  EXPECT_TRUE(estimators.extraTargets().empty());
  const auto old_view = roiCloud(s.scene, 1, s.cameras[0]);
  estimators.insertView(old_view.cloud, old_view.roi_indices, old_view.transform, 50.0, nullptr, &ticket);
  EXPECT_EQ(estimators.viewsFromBeforeAReset(), 1u);
  EXPECT_EQ(estimators.viewsSkipped(), 0u);  // expected around a reset: not a loss
  ASSERT_TRUE(estimators.waitForFits(10.0));
  const auto& plugin = dynamic_cast<const ShapeEstimatorPlugin&>(estimators.host().estimator(0));
  EXPECT_EQ(diagnosticCount(plugin, "views"), 0u) << "a view from before the reset reached the new map";
  // With the current count it goes in.
  const std::uint64_t now = estimators.resets();
  estimators.insertView(old_view.cloud, old_view.roi_indices, old_view.transform, 51.0, nullptr, &now);
  EXPECT_EQ(estimators.viewsFromBeforeAReset(), 1u);
  EXPECT_EQ(diagnosticCount(plugin, "views"), 1u);
}

// fruit_mapping_node's input and output as upstream names them: PointcloudWithRoi in, the
// superellipsoids out (the last message kept).
struct MappingNodeTopics {
  ros::NodeHandle nh;
  ros::Publisher pub = nh.advertise<pointcloud_roi_msgs::PointcloudWithRoi>(ros_io::kUpstreamRoiTopic, 10);
  topic_tools::ShapeShifter::ConstPtr last;
  ros::Subscriber sub = nh.subscribe<topic_tools::ShapeShifter>(
      ros_io::kUpstreamSuperellipsoidsTopic, 5, [this](const topic_tools::ShapeShifter::ConstPtr& m) { last = m; });
  bool connected() {
    return waitFor([&] { return pub.getNumSubscribers() > 0 && sub.getNumPublishers() > 0; }, 30.0);
  }
};

TEST(FruitMappingNode, TakesUpstreamRoiCloudsAndPublishesUpstreamSuperellipsoids) {
  MappingNodeTopics topics;
  ASSERT_TRUE(topics.connected());
  const FruitOnALeaf s;
  for (const auto& camera : s.cameras) {
    topics.pub.publish(roiCloud(s.scene, 1, camera));
    ros::WallDuration(0.2).sleep();
  }
  superellipsoid_msgs::SuperellipsoidArray arr;
  ASSERT_TRUE(waitFor([&] {
    if (!topics.last) return false;
    arr = asSuperellipsoidArray(*topics.last);
    return arr.superellipsoids.size() == 1 && topics.last->getDataType() == "superellipsoid_msgs/SuperellipsoidArray";
  }, 60.0)) << (topics.last ? topics.last->getDataType() : std::string("nothing received"));
  EXPECT_EQ(topics.last->getMD5Sum(), ros::message_traits::md5sum<superellipsoid_msgs::SuperellipsoidArray>());
  EXPECT_NE(topics.last->getMessageDefinition().find("MSG: superellipsoid_msgs/Superellipsoid"), std::string::npos);
  // Field by field: the shape, pose (angles in degrees) and volume describe the true fruit.
  const auto& m = arr.superellipsoids[0];
  EXPECT_EQ(arr.header.frame_id, "world");
  EXPECT_EQ(m.header.frame_id, "world");
  EXPECT_TRUE(m.object_tracking);
  Superellipsoid fit;
  fit.a = m.a, fit.b = m.b, fit.c = m.c, fit.e1 = m.e1, fit.e2 = m.e2;
  fit.t = Eigen::Vector3d(m.tx, m.ty, m.tz);
  fit.rpy = Eigen::Vector3d(m.roll, m.pitch, m.yaw) * M_PI / 180.0;
  EXPECT_NEAR(m.volume, fit.volume(), 1e-9);
  EXPECT_LT((fit.t - s.truth.t).norm(), 0.01);
  EXPECT_NEAR(m.volume, s.truth.volume(), 0.25 * s.truth.volume());
  // The seen side of the true surface lies on the published surface (angles read as degrees).
  int on_surface = 0, seen = 0;
  for (const auto& camera : s.cameras) {
    const DepthScan scan = renderDepth(s.scene, PinholeCamera::lookingAt(camera.position, s.truth.t, 64, 48));
    for (std::size_t i = 0; i < scan.points.size(); ++i)
      if (scan.labels[i] == 0) {
        ++seen;
        on_surface += std::abs(fit.radialDistance(scan.points[i])) < 0.006;
      }
  }
  ASSERT_GT(seen, 100);
  EXPECT_GT(on_surface, 0.8 * seen);

  // Diagnostics: the estimator is running and reports its map.
  diagnostic_msgs::DiagnosticStatus diag;
  ros::Subscriber dsub = topics.nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& a) {
        for (const auto& st : a->status)
          if (st.name.find("fruit_mapping_node") != std::string::npos &&  // not the sim planner's estimator
              st.name.find("shape estimator superellipsoid") != std::string::npos)
            diag = st;
      });
  ASSERT_TRUE(waitFor([&] { return !diag.name.empty(); }, 10.0));
  // Running, and warning that no camera frame came with the views (the plugin's default camera
  // topic has no publisher here): each view went in as its 1 cm cloud.
  EXPECT_EQ(diag.level, diagnostic_msgs::DiagnosticStatus::WARN) << diag.message;
  EXPECT_NE(diag.message.find("views without their camera frame"), std::string::npos) << diag.message;
  bool has_blocks = false;
  for (const auto& kv : diag.values) has_blocks |= kv.key == "map blocks" && kv.value.rfind("0 ", 0) != 0;
  EXPECT_TRUE(has_blocks);

  // save_map, clear_map (node-wide), load_map: the fruit comes back from the file.
  const std::string file = "/tmp/fsc_rostest_map_" + std::to_string(::getpid()) + ".tsdf";
  fruit_shape_completion::FilePath save, load;
  save.request.file_path = load.request.file_path = file;
  ASSERT_TRUE(ros::service::call("/fruit_mapping_node/superellipsoid/save_map", save));
  EXPECT_TRUE(save.response.success) << save.response.message;
  std_srvs::Empty clear;
  ASSERT_TRUE(ros::service::call("/fruit_mapping_node/clear_map", clear));
  ASSERT_TRUE(waitFor([&] {
    if (!topics.last) return false;
    arr = asSuperellipsoidArray(*topics.last);
    return arr.superellipsoids.empty();
  }, 10.0)) << "clear_map left fruits";
  ASSERT_TRUE(ros::service::call("/fruit_mapping_node/superellipsoid/load_map", load));
  EXPECT_TRUE(load.response.success) << load.response.message;
  ASSERT_TRUE(waitFor([&] {
    arr = asSuperellipsoidArray(*topics.last);
    return arr.superellipsoids.size() == 1;
  }, 10.0)) << "load_map did not bring the fruit back";
  EXPECT_LT((Eigen::Vector3d(arr.superellipsoids[0].tx, arr.superellipsoids[0].ty, arr.superellipsoids[0].tz) - s.truth.t).norm(), 0.01);
  load.request.file_path = "/nonexistent/map.tsdf";
  ASSERT_TRUE(ros::service::call("/fruit_mapping_node/superellipsoid/load_map", load));
  EXPECT_FALSE(load.response.success);
  EXPECT_NE(load.response.message.find("/nonexistent/map.tsdf"), std::string::npos) << load.response.message;
  std::remove(file.c_str());
}

// A cloud outside the map frame is taken there by tf at its stamp, its message's transform read as
// the sensor's pose in the cloud's frame: a cloud in the camera frame (identity), and one in
// another fixed frame as pointcloud_roi publishes in its own map frame (the camera's pose there).
// One whose frame tf does not know is skipped and counted.
TEST(FruitMappingNode, CloudsInAnotherFrameAreTakenToTheMapByTf) {
  MappingNodeTopics topics;
  ASSERT_TRUE(topics.connected());
  std_srvs::Empty clear;
  ASSERT_TRUE(ros::service::call("/fruit_mapping_node/clear_map", clear));
  tf2_ros::TransformBroadcaster tf;
  const FruitOnALeaf s;
  const std::string frame = "fsc_test_camera_" + std::to_string(::getpid());
  // A second of the frame's transform first: the node's tf listener connects to this publisher.
  for (int i = 0; i < 10; ++i) {
    geometry_msgs::TransformStamped warm;
    warm.header.stamp = ros::Time::now();
    warm.header.frame_id = "world";
    warm.child_frame_id = frame;
    warm.transform.rotation.w = 1.0;
    tf.sendTransform(warm);
    ros::WallDuration(0.1).sleep();
  }
  for (const auto& camera : s.cameras) {
    pointcloud_roi_msgs::PointcloudWithRoi msg = roiCloud(s.scene, 1, camera, /*in_camera_frame=*/true);
    geometry_msgs::TransformStamped pose;
    pose.transform = msg.transform;
    pose.header.stamp = ros::Time::now();
    pose.header.frame_id = "world";
    pose.child_frame_id = frame;
    tf.sendTransform(pose);
    msg.cloud.header.frame_id = frame;
    msg.cloud.header.stamp = pose.header.stamp;
    msg.transform = geometry_msgs::Transform();  // the sensor in its own frame
    msg.transform.rotation.w = 1.0;
    ros::WallDuration(0.05).sleep();
    topics.pub.publish(msg);
    ros::WallDuration(0.2).sleep();
  }
  superellipsoid_msgs::SuperellipsoidArray arr;
  auto oneFruitAtTheTruth = [&](const std::string& what) {
    ASSERT_TRUE(waitFor([&] {
      if (!topics.last) return false;
      arr = asSuperellipsoidArray(*topics.last);
      return arr.superellipsoids.size() == 1;
    }, 60.0)) << "no fruit from clouds " << what;
    const auto& m = arr.superellipsoids[0];
    EXPECT_LT((Eigen::Vector3d(m.tx, m.ty, m.tz) - s.truth.t).norm(), 0.01) << what;
    EXPECT_NEAR(m.volume, s.truth.volume(), 0.25 * s.truth.volume()) << what;
  };
  oneFruitAtTheTruth("in the camera frame");

  // pointcloud_roi's own map frame 4 m from the node's: the sensor's pose there comes with the
  // message. Taken for the sensor, that frame's origin would put every point beyond max_range.
  ASSERT_TRUE(ros::service::call("/fruit_mapping_node/clear_map", clear));
  ASSERT_TRUE(waitFor([&] { return topics.last && asSuperellipsoidArray(*topics.last).superellipsoids.empty(); }, 10.0));
  tf2_ros::StaticTransformBroadcaster static_tf;
  const std::string roi_frame = "fsc_test_roi_map_" + std::to_string(::getpid());
  Eigen::Isometry3d roi_from_world = Eigen::Isometry3d::Identity();
  roi_from_world.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  roi_from_world.translation() = Eigen::Vector3d(4.0, 0.0, 0.0);
  geometry_msgs::TransformStamped world_roi = tf2::eigenToTransform(roi_from_world.inverse());
  world_roi.header.stamp = ros::Time::now();
  world_roi.header.frame_id = "world";
  world_roi.child_frame_id = roi_frame;
  static_tf.sendTransform(world_roi);
  ros::WallDuration(1.0).sleep();
  for (const auto& camera : s.cameras) {
    pointcloud_roi_msgs::PointcloudWithRoi msg = roiCloud(s.scene, 1, camera);  // world coordinates
    for (sensor_msgs::PointCloud2Iterator<float> x(msg.cloud, "x"), y(msg.cloud, "y"), z(msg.cloud, "z"); x != x.end();
         ++x, ++y, ++z) {
      const Eigen::Vector3d q = roi_from_world * Eigen::Vector3d(*x, *y, *z);
      *x = static_cast<float>(q.x()), *y = static_cast<float>(q.y()), *z = static_cast<float>(q.z());
    }
    msg.transform = tf2::eigenToTransform(roi_from_world * tf2::transformToEigen(msg.transform)).transform;
    msg.cloud.header.frame_id = roi_frame;
    msg.cloud.header.stamp = ros::Time::now();
    topics.pub.publish(msg);
    ros::WallDuration(0.2).sleep();
  }
  oneFruitAtTheTruth("in pointcloud_roi's map frame");

  // A frame tf has never heard of: skipped, counted in /diagnostics, the fruit kept.
  std::string views_value;
  ros::Subscriber diag = topics.nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& a) {
        for (const auto& st : a->status) {
          if (st.name != "fruit_mapping_node: shape estimators: PointcloudWithRoi input") continue;
          for (const auto& kv : st.values)
            if (kv.key.rfind("views skipped", 0) == 0) views_value = kv.value;
        }
      });
  ASSERT_TRUE(waitFor([&] { return !views_value.empty(); }, 10.0));
  const std::string before = views_value;
  pointcloud_roi_msgs::PointcloudWithRoi lost = roiCloud(s.scene, 1, s.cameras[0], /*in_camera_frame=*/true);
  lost.cloud.header.frame_id = "fsc_no_such_frame";
  lost.cloud.header.stamp = ros::Time::now();
  topics.pub.publish(lost);
  const std::string after = std::to_string(std::stoul(before) + 1);
  EXPECT_TRUE(waitFor([&] { return views_value == after; }, 10.0)) << "views skipped: " << before << " -> " << views_value;
  ros::WallDuration(0.5).sleep();
  arr = asSuperellipsoidArray(*topics.last);
  ASSERT_EQ(arr.superellipsoids.size(), 1u);
  EXPECT_LT((Eigen::Vector3d(arr.superellipsoids[0].tx, arr.superellipsoids[0].ty, arr.superellipsoids[0].tz) - s.truth.t).norm(), 0.01);
  ASSERT_TRUE(ros::service::call("/fruit_mapping_node/clear_map", clear));
}

TEST(Plugin, LoadsByNameThroughPluginlib) {
  pluginlib::ClassLoader<ShapeEstimatorPlugin> loader("fruit_shape_completion", "fruit_shape_completion::ShapeEstimatorPlugin");
  const auto classes = loader.getDeclaredClasses();
  ASSERT_NE(std::find(classes.begin(), classes.end(), "fruit_shape_completion/SuperellipsoidEstimator"), classes.end());
  std::unique_ptr<ShapeEstimatorPlugin> plugin(loader.createUnmanagedInstance("fruit_shape_completion/SuperellipsoidEstimator"));
  ros::NodeHandle nh("~/plugin_test");
  nh.setParam("superellipsoids_topic", "superellipsoids");
  plugin->initialize("plugin_test", nh, "world");
  EXPECT_EQ(plugin->name(), "plugin_test");
  // It works: a half-seen fruit in, a fit out.
  const HalfSeenFruit view;
  const Superellipsoid& truth = view.truth;
  const PointList& fruit = view.fruit;
  const PointList none;
  const Eigen::Isometry3d& pose = view.pose;
  plugin->insertView(host::ViewData{fruit, none, pose, 0.0});
  plugin->update();
  ASSERT_EQ(plugin->fruits().size(), 1u);
  EXPECT_NEAR(plugin->fruits()[0].volume, truth.volume(), 0.1 * truth.volume());
  plugin.reset();
}

// A configuration written for an older version says publish_targets: dynamic_reconfigure, which
// knows only shape_targets, must not switch the targets back on with its default.
TEST(Plugin, TheOlderPublishTargetsNameStillSwitchesTargetsOff) {
  pluginlib::ClassLoader<ShapeEstimatorPlugin> loader("fruit_shape_completion", "fruit_shape_completion::ShapeEstimatorPlugin");
  std::unique_ptr<ShapeEstimatorPlugin> plugin(loader.createUnmanagedInstance("fruit_shape_completion/SuperellipsoidEstimator"));
  ros::NodeHandle nh("~/legacy_targets");
  nh.setParam("superellipsoids_topic", "legacy_superellipsoids");
  nh.setParam("publish_targets", false);
  plugin->initialize("legacy_targets", nh, "world");
  const HalfSeenFruit view;
  const Superellipsoid& truth = view.truth;
  const PointList& fruit = view.fruit;
  const PointList none;
  const Eigen::Isometry3d& pose = view.pose;
  std::atomic<int> published{0};
  ros::NodeHandle top;
  ros::Subscriber sub = top.subscribe<superellipsoid_msgs::SuperellipsoidArray>(
      nh.resolveName("legacy_superellipsoids"), 4, [&](const superellipsoid_msgs::SuperellipsoidArray::ConstPtr&) { ++published; });
  ASSERT_TRUE(waitFor([&] { return sub.getNumPublishers() > 0; }, 10.0));
  plugin->insertView(host::ViewData{fruit, none, pose, 0.0});
  plugin->update();
  ASSERT_EQ(plugin->fruits().size(), 1u);
  EXPECT_TRUE(plugin->extraTargets().empty());
  bool on = true;
  EXPECT_TRUE(nh.getParam("shape_targets", on));
  EXPECT_FALSE(on);
  // Updates without a new view publish nothing new (the topics are latched).
  ASSERT_TRUE(waitFor([&] { return published.load() == 1; }, 10.0));
  plugin->update();
  plugin->update();
  plugin->insertView(host::ViewData{fruit, none, pose, 1.0});
  plugin->update();
  ASSERT_TRUE(waitFor([&] { return published.load() >= 2; }, 10.0));
  ros::WallDuration(0.5).sleep();  // anything published in between would have arrived by now
  EXPECT_EQ(published.load(), 2);
  plugin.reset();
}

TEST(Plugin, FullResolutionFruitCloudTopicFeedsTheMapInsteadOfThePlannersViews) {
  pluginlib::ClassLoader<ShapeEstimatorPlugin> loader("fruit_shape_completion", "fruit_shape_completion::ShapeEstimatorPlugin");
  std::unique_ptr<ShapeEstimatorPlugin> plugin(loader.createUnmanagedInstance("fruit_shape_completion/SuperellipsoidEstimator"));
  ros::NodeHandle nh("~/fullres");
  nh.setParam("superellipsoids_topic", "superellipsoids");
  nh.setParam("fruit_cloud_topic", "fruit_cloud");
  plugin->initialize("fullres", nh, "world");
  const FruitOnALeaf s;
  // A planner view is ignored: the topic feeds the map.
  const auto coarse = roiCloud(s.scene, 1, s.cameras[0]);
  PointList all, fruit;
  std::size_t bad = 0;
  std::string err;
  ASSERT_TRUE(ros_io::fromRoiCloud(coarse.cloud, coarse.roi_indices, &all, &fruit, &bad, &err));
  plugin->insertView({fruit, all, tf2::transformToEigen(coarse.transform), 0.0});
  plugin->update();
  EXPECT_TRUE(plugin->fruits().empty());
  // Full-resolution fruit points in the camera frames, poses on tf.
  tf2_ros::StaticTransformBroadcaster tf;
  ros::Publisher pub = nh.advertise<sensor_msgs::PointCloud2>("fruit_cloud", 10);
  ASSERT_TRUE(waitFor([&] { return pub.getNumSubscribers() > 0; }, 10.0));
  std::vector<geometry_msgs::TransformStamped> poses;
  for (std::size_t i = 0; i < s.cameras.size(); ++i) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = s.cameras[i].rotation;
    pose.translation() = s.cameras[i].position;
    geometry_msgs::TransformStamped t = tf2::eigenToTransform(pose);
    t.header.frame_id = "world";
    t.child_frame_id = "fullres_camera_" + std::to_string(i);
    poses.push_back(t);
  }
  tf.sendTransform(poses);
  // The planner's view above was ignored, so the estimator counts only the clouds. One cloud at
  // a time: the subscriber keeps the newest 2, as a camera stream needs.
  auto views = [&] {
    for (const auto& kv : plugin->diagnostics())
      if (kv.first == "views") return std::stoul(kv.second);
    return 0ul;
  };
  for (std::size_t i = 0; i < s.cameras.size(); ++i) {
    const DepthScan scan = renderDepth(s.scene, s.cameras[i], 0.0005, 5);
    PointList local;
    Eigen::Isometry3d pose = tf2::transformToEigen(poses[i].transform);
    for (std::size_t k = 0; k < scan.points.size(); ++k)
      if (scan.labels[k] == 0) local.push_back(pose.inverse() * scan.points[k]);
    pub.publish(ros_io::toCloud(local, poses[i].child_frame_id, ros::Time(0)));
    ASSERT_TRUE(waitFor([&] { return views() == i + 1; }, 10.0)) << views() << " clouds integrated of " << i + 1;
  }
  ASSERT_EQ(plugin->fruits().size(), 1u);
  EXPECT_LT((plugin->fruits()[0].center() - s.truth.t).norm(), 0.005);
  EXPECT_NEAR(plugin->fruits()[0].volume, s.truth.volume(), 0.1 * s.truth.volume());
  // A detector's NaN points are dropped on reading, and counted.
  const std::size_t skipped = diagnosticCount(*plugin, "points skipped (NaN/Inf, range)");
  const PointList nans(5, Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  pub.publish(ros_io::toCloud(nans, poses[0].child_frame_id, ros::Time(0)));
  ASSERT_TRUE(waitFor([&] { return diagnosticCount(*plugin, "points skipped (NaN/Inf, range)") >= skipped + 5; }, 10.0));
  EXPECT_EQ(diagnosticCount(*plugin, "points skipped (NaN/Inf, range)"), skipped + 5);
  EXPECT_EQ(plugin->fruits().size(), 1u);
  // Clouds that cannot be placed are skipped and counted: one in the map frame (no sensor
  // origin), one in a frame tf does not know.
  const std::string clouds_skipped = "fruit clouds skipped (malformed, wrong frame, no transform, dropped)";
  EXPECT_EQ(diagnosticCount(*plugin, clouds_skipped), 0u);
  pub.publish(ros_io::toCloud(PointList(3, s.truth.t), "world", ros::Time(0)));
  pub.publish(ros_io::toCloud(PointList(3, s.truth.t), "fsc_unknown_frame", ros::Time(0)));
  EXPECT_TRUE(waitFor([&] { return diagnosticCount(*plugin, clouds_skipped) == 2; }, 10.0))
      << diagnosticCount(*plugin, clouds_skipped);
  // Each skipped cloud counts, not only those whose throttled warning prints: three more in the
  // map frame, each within the warning's 10 s.
  for (std::size_t k = 3; k <= 5; ++k) {
    pub.publish(ros_io::toCloud(PointList(3, s.truth.t), "world", ros::Time(0)));
    EXPECT_TRUE(waitFor([&] { return diagnosticCount(*plugin, clouds_skipped) == k; }, 10.0))
        << diagnosticCount(*plugin, clouds_skipped) << " skipped, " << k << " expected";
  }
  EXPECT_EQ(plugin->fruits().size(), 1u);
  plugin.reset();
}

TEST(Plugin, CameraFramesPairedWithThePlannersViewsFeedTheMapAtFullResolution) {
  pluginlib::ClassLoader<ShapeEstimatorPlugin> loader("fruit_shape_completion", "fruit_shape_completion::ShapeEstimatorPlugin");
  ros::NodeHandle nh;
  std::unique_ptr<ShapeEstimatorPlugin> plugin = cameraPlugin(loader, "camera", &nh);
  auto count = [&](const std::string& key) { return diagnosticCount(*plugin, key); };
  const FruitOnALeaf s;
  tf2_ros::StaticTransformBroadcaster tf;
  const auto poses = sendCameraPoses(s, "camera_optical_", &tf);
  ros::Publisher pub = nh.advertise<sensor_msgs::PointCloud2>("camera_points", 4);
  ASSERT_TRUE(waitFor([&] { return pub.getNumSubscribers() > 0; }, 10.0));
  // Each planner view (pointcloud_roi's 1 cm cloud, stamped as the camera frame it came from)
  // is paired with its frame: the map gets the full-resolution frame through the input stage.
  std::size_t views = 0;
  for (std::size_t i = 0; i < s.cameras.size(); ++i) {
    const ros::Time stamp(1000.0 + i);
    pub.publish(ros_io::toOrganizedCloud(organizedRender(s.scene, s.cameras[i]), poses[i].child_frame_id, stamp));
    ASSERT_TRUE(waitFor([&] { return count("camera frames received") == i + 1; }, 10.0));
    const auto coarse = roiCloud(s.scene, 1, s.cameras[i]);
    PointList all, fruit;
    std::size_t bad = 0;
    std::string err;
    ASSERT_TRUE(ros_io::fromRoiCloud(coarse.cloud, coarse.roi_indices, &all, &fruit, &bad, &err));
    plugin->insertView({fruit, all, tf2::transformToEigen(coarse.transform), stamp.toSec(), host::ViewSource::kRoiCloud});
    ++views;
    EXPECT_EQ(count("views fed by their camera frame"), i + 1);
  }
  plugin->update();
  ASSERT_EQ(plugin->fruits().size(), 1u);
  EXPECT_LT((plugin->fruits()[0].center() - s.truth.t).norm(), 0.005);
  EXPECT_NEAR(plugin->fruits()[0].volume, s.truth.volume(), 0.1 * s.truth.volume());
  EXPECT_GT(count("input: dropped at depth edges"), 0u);
  EXPECT_EQ(plugin->diagnosticsWarning(), "");  // nothing lost: its diagnostics say OK
  // A view whose frame never came goes in with its own cloud, counted, and the diagnostics warn.
  const auto coarse = roiCloud(s.scene, 1, s.cameras[0]);
  PointList all, fruit;
  std::size_t bad = 0;
  std::string err;
  ASSERT_TRUE(ros_io::fromRoiCloud(coarse.cloud, coarse.roi_indices, &all, &fruit, &bad, &err));
  plugin->insertView({fruit, all, tf2::transformToEigen(coarse.transform), 5000.0, host::ViewSource::kRoiCloud});
  EXPECT_EQ(count("views fed by their own (1 cm) cloud: no frame paired"), 1u);
  EXPECT_EQ(count("  of which: no frame within the tolerance"), 1u);
  EXPECT_EQ(count("views"), views + 1);
  EXPECT_NE(plugin->diagnosticsWarning().find("1 views without their camera frame"), std::string::npos)
      << plugin->diagnosticsWarning();
  // A cloud that is not organized is ignored and counted; a stamp back in time (a looping bag)
  // clears the buffer, keeps the map and is counted.
  pub.publish(ros_io::toCloud(all, poses[0].child_frame_id, ros::Time(2000.0)));
  EXPECT_TRUE(waitFor([&] { return count("camera clouds not organized (ignored)") == 1; }, 10.0));
  pub.publish(ros_io::toOrganizedCloud(organizedRender(s.scene, s.cameras[0]), poses[0].child_frame_id, ros::Time(10.0)));
  EXPECT_TRUE(waitFor([&] { return count("camera clock jumps back (buffer cleared)") == 1; }, 10.0));
  EXPECT_EQ(plugin->fruits().size(), 1u);
  // ... and goes on at the bag's new time: a view stamped like the new frame pairs with it.
  const std::size_t fed = count("views fed by their camera frame");
  plugin->insertView({fruit, all, tf2::transformToEigen(coarse.transform), 10.0, host::ViewSource::kRoiCloud});
  EXPECT_EQ(count("views fed by their camera frame"), fed + 1);
  EXPECT_EQ(count("camera clock jumps back (buffer cleared)"), 1u);  // warned once, not per frame
  EXPECT_EQ(plugin->fruits().size(), 1u);
  plugin.reset();
}

// Live settings through dynamic_reconfigure (as rqt_reconfigure and dynparam set them), and
// the fruit report a grower opens, read back against the fruits the plugin publishes.
TEST(Plugin, LiveSettingsThroughDynamicReconfigureAndAFruitExport) {
  pluginlib::ClassLoader<ShapeEstimatorPlugin> loader("fruit_shape_completion", "fruit_shape_completion::ShapeEstimatorPlugin");
  ros::NodeHandle nh;
  std::unique_ptr<ShapeEstimatorPlugin> plugin = cameraPlugin(loader, "live", &nh);
  auto count = [&](const std::string& key) { return diagnosticCount(*plugin, key); };
  const FruitOnALeaf s;
  tf2_ros::StaticTransformBroadcaster tf;
  const auto poses = sendCameraPoses(s, "live_optical_", &tf);
  ros::Publisher pub = nh.advertise<sensor_msgs::PointCloud2>("live_points", 4);
  ASSERT_TRUE(waitFor([&] { return pub.getNumSubscribers() > 0; }, 10.0));
  std::size_t frames = 0;
  auto view = [&](std::size_t i, double t) {
    pub.publish(ros_io::toOrganizedCloud(organizedRender(s.scene, s.cameras[i]), poses[i].child_frame_id, ros::Time(t)));
    ++frames;
    ASSERT_TRUE(waitFor([&] { return count("camera frames received") == frames; }, 10.0));
    const auto coarse = roiCloud(s.scene, 1, s.cameras[i]);
    PointList all, fruit;
    std::size_t bad = 0;
    std::string err;
    ASSERT_TRUE(ros_io::fromRoiCloud(coarse.cloud, coarse.roi_indices, &all, &fruit, &bad, &err));
    plugin->insertView({fruit, all, tf2::transformToEigen(coarse.transform), t, host::ViewSource::kRoiCloud});
  };
  superellipsoid_msgs::SuperellipsoidArray published;
  ros::Subscriber sub = nh.subscribe<superellipsoid_msgs::SuperellipsoidArray>(
      "superellipsoids", 2, [&](const superellipsoid_msgs::SuperellipsoidArray::ConstPtr& m) { published = *m; });
  for (std::size_t i = 0; i < s.cameras.size(); ++i) view(i, 100.0 + i);
  ASSERT_TRUE(waitFor([&] { return sub.getNumPublishers() > 0; }, 10.0));
  plugin->update();
  ASSERT_EQ(plugin->fruits().size(), 1u);
  ASSERT_TRUE(waitFor([&] { return published.superellipsoids.size() == 1; }, 10.0));
  ASSERT_GT(plugin->extraTargets().size(), 10u);

  // A reconfigure call, from another thread while this one spins (as from rqt).
  auto reconfigure = [&](dynamic_reconfigure::Reconfigure srv) {
    auto call = std::async(std::launch::async, [&] { return ros::service::call(nh.resolveName("set_parameters"), srv); });
    EXPECT_TRUE(waitFor([&] { return call.wait_for(std::chrono::seconds(0)) == std::future_status::ready; }, 10.0));
    EXPECT_TRUE(call.get());
    return srv.response.config;
  };
  ASSERT_TRUE(ros::service::waitForService(nh.resolveName("set_parameters"), 10000));
  dynamic_reconfigure::Reconfigure off;
  dynamic_reconfigure::BoolParameter targets;
  targets.name = "shape_targets";
  targets.value = false;
  off.request.config.bools.push_back(targets);
  reconfigure(off);
  EXPECT_TRUE(plugin->extraTargets().empty()) << "shape targets still handed out after switching them off";
  EXPECT_EQ(plugin->fruits().size(), 1u);  // fitting goes on
  double param = 0;
  EXPECT_TRUE(nh.getParam("target_offset", param));  // the server keeps the namespace's values
  bool on = true;
  EXPECT_TRUE(nh.getParam("shape_targets", on));
  EXPECT_FALSE(on);
  // Back on, and no view comes (the planner stands still): the change asks for an update itself.
  dynamic_reconfigure::Reconfigure back;
  targets.value = true;
  back.request.config.bools.push_back(targets);
  reconfigure(back);
  EXPECT_TRUE(waitFor([&] { return !plugin->extraTargets().empty(); }, 10.0))
      << "targets switched back on came only with the next view";

  // A red threshold: before, a view masks the pepper's pixels; with saturation >= 255 asked
  // for, the next view masks none.
  const std::size_t before = count("input: fruit points masked");
  view(0, 200.0);
  const std::size_t red = count("input: fruit points masked") - before;
  EXPECT_GT(red, 100u);
  dynamic_reconfigure::Reconfigure strict;
  dynamic_reconfigure::IntParameter saturation;
  saturation.name = "red_min_saturation";
  saturation.value = 255;
  strict.request.config.ints.push_back(saturation);
  reconfigure(strict);
  const std::size_t after = count("input: fruit points masked");
  view(0, 201.0);
  EXPECT_EQ(count("input: fruit points masked") - after, 0u) << "the new red threshold did not reach the next view";

  // A bad combination is refused whole: min hue above max hue.
  dynamic_reconfigure::Reconfigure bad;
  dynamic_reconfigure::IntParameter hue;
  hue.name = "red_min_hue";
  hue.value = 100;
  bad.request.config.ints.push_back(hue);
  const auto config = reconfigure(bad);
  for (const auto& p : config.ints)
    if (p.name == "red_min_hue") EXPECT_EQ(p.value, -20);

  // export_fruits: one row per accepted fruit, the published superellipsoid's numbers.
  const std::string path = "/tmp/fruit_shape_completion_export_" + std::to_string(getpid()) + ".csv";
  FilePath exp;
  exp.request.file_path = path;
  auto call = std::async(std::launch::async, [&] { return ros::service::call(nh.resolveName("export_fruits"), exp); });
  ASSERT_TRUE(waitFor([&] { return call.wait_for(std::chrono::seconds(0)) == std::future_status::ready; }, 10.0));
  ASSERT_TRUE(call.get());
  ASSERT_TRUE(exp.response.success) << exp.response.message;
  std::ifstream in(path);
  std::string header, row, extra;
  std::getline(in, header);
  std::getline(in, row);
  EXPECT_FALSE(std::getline(in, extra) && !extra.empty());
  EXPECT_EQ(header.rfind("id,x,y,z,volume_m3,", 0), 0u) << header;
  std::vector<double> cells;
  std::istringstream rs(row);
  for (std::string c; std::getline(rs, c, ',');) cells.push_back(c.empty() ? std::nan("") : std::stod(c));
  ASSERT_GE(cells.size(), 17u);
  const superellipsoid_msgs::Superellipsoid& m = published.superellipsoids[0];
  EXPECT_EQ(static_cast<unsigned>(cells[0]), m.id);
  EXPECT_NEAR(cells[1], m.tx, 1e-6);
  EXPECT_NEAR(cells[2], m.ty, 1e-6);
  EXPECT_NEAR(cells[3], m.tz, 1e-6);
  EXPECT_NEAR(cells[4], m.volume, 1e-9);
  EXPECT_NEAR(cells[5], m.a, 1e-6);
  EXPECT_NEAR(cells[9], m.e2, 1e-6);
  EXPECT_NEAR(cells[12], m.yaw, 1e-4);
  // The views matched at the last fit: the eight cameras, and the view at 200 s back at camera
  // 0 after the others once the update a reconfigure asks for has fitted it (the one at 201 s
  // masks nothing).
  EXPECT_GE(cells[14], 1.0);
  EXPECT_LE(cells[14], static_cast<double>(s.cameras.size() + 1));
  EXPECT_NEAR(cells[15], 100.0, 1e-6);  // the first view's stamp
  std::remove(path.c_str());
  plugin.reset();
}

// An external detector's mask (camera_mask_topic) replaces the red test for the frame with its
// stamp; a mask that does not fit, or none, leaves the red test to decide, counted.
TEST(Plugin, ADetectorsMaskReplacesTheRedTest) {
  pluginlib::ClassLoader<ShapeEstimatorPlugin> loader("fruit_shape_completion", "fruit_shape_completion::ShapeEstimatorPlugin");
  std::unique_ptr<ShapeEstimatorPlugin> plugin(loader.createUnmanagedInstance("fruit_shape_completion/SuperellipsoidEstimator"));
  ros::NodeHandle nh("~/masked");
  nh.setParam("superellipsoids_topic", "superellipsoids");
  nh.setParam("camera_cloud_topic", "masked_points");
  nh.setParam("camera_mask_topic", "masked_mask");
  plugin->initialize("masked", nh, "world");
  auto count = [&](const std::string& key) { return diagnosticCount(*plugin, key); };
  const FruitOnALeaf s;
  tf2_ros::StaticTransformBroadcaster tf;
  geometry_msgs::TransformStamped pose = tf2::eigenToTransform(sim::cameraPose(s.cameras[0]));
  pose.header.frame_id = "world";
  pose.child_frame_id = "masked_optical";
  tf.sendTransform(pose);
  ros::Publisher cloud_pub = nh.advertise<sensor_msgs::PointCloud2>("masked_points", 4);
  ros::Publisher mask_pub = nh.advertise<sensor_msgs::Image>("masked_mask", 4);
  ASSERT_TRUE(waitFor([&] { return cloud_pub.getNumSubscribers() > 0 && mask_pub.getNumSubscribers() > 0; }, 10.0));
  const OrganizedFrame frame = organizedRender(s.scene, s.cameras[0]);
  const auto coarse = roiCloud(s.scene, 1, s.cameras[0]);
  PointList all, fruit;
  std::size_t bad = 0;
  std::string err;
  ASSERT_TRUE(ros_io::fromRoiCloud(coarse.cloud, coarse.roi_indices, &all, &fruit, &bad, &err));
  std::size_t frames = 0, masks = 0;
  // One view at `t`: its frame and, if `value` >= 0, a width x height mask of that value.
  auto view = [&](double t, int value, unsigned width, unsigned height) {
    if (value >= 0) {
      sensor_msgs::Image m;
      m.header.stamp = ros::Time(t);
      m.width = width;
      m.height = height;
      m.encoding = "mono8";
      m.step = width;
      m.data.assign(std::size_t(width) * height, static_cast<std::uint8_t>(value));
      mask_pub.publish(m);
      ++masks;
      ASSERT_TRUE(waitFor([&] { return count("camera masks received") == masks; }, 10.0));
    }
    cloud_pub.publish(ros_io::toOrganizedCloud(frame, "masked_optical", ros::Time(t)));
    ++frames;
    ASSERT_TRUE(waitFor([&] { return count("camera frames received") == frames; }, 10.0));
    plugin->insertView({fruit, all, tf2::transformToEigen(coarse.transform), t, host::ViewSource::kRoiCloud});
  };
  const unsigned w = static_cast<unsigned>(frame.width), h = static_cast<unsigned>(frame.height);
  // The detector sees no fruit: nothing is masked, though the red test would find the pepper.
  view(3000.0, 0, w, h);
  EXPECT_EQ(count("views fed by their camera frame"), 1u);
  EXPECT_EQ(count("input: fruit points masked"), 0u);
  // The detector calls every pixel fruit: every pixel with depth is masked, far more than red.
  view(3001.0, 255, w, h);
  const std::size_t all_pixels = count("input: fruit points masked");
  EXPECT_GT(all_pixels, 0u);
  // A mask of another size is refused and the red test decides: fewer points than every pixel.
  view(3002.0, 255, 10, 10);
  EXPECT_EQ(count("camera masks refused (not mono8, wrong size)"), 1u);
  const std::size_t red = count("input: fruit points masked") - all_pixels;
  EXPECT_GT(red, 0u);
  EXPECT_LT(red, all_pixels);
  // A frame whose mask never came: the red test again, counted.
  view(3003.0, -1, w, h);
  EXPECT_EQ(count("camera frames without their mask (red test used)"), 1u);
  EXPECT_EQ(count("views fed by their camera frame"), 4u);
  plugin.reset();
}

TEST(Plugin, WrongNameOrBadParameterFailsAtStartWithAMessage) {
  ros::NodeHandle nh("~/bad_name");
  setOneEstimator(nh, "shape", "fruit_shape_completion/NoSuchEstimator");
  ros_io::ShapeEstimatorLoader loader;
  try {
    loader.load(nh, "world");
    FAIL() << "an unknown plugin type must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("NoSuchEstimator"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("SuperellipsoidEstimator"), std::string::npos) << e.what();  // known types listed
  }
  ros::NodeHandle bad("~/bad_param");
  setOneEstimator(bad, "shape", "fruit_shape_completion/SuperellipsoidEstimator");
  bad.setParam("shape/alpha", -1.0);
  try {
    loader.load(bad, "world");
    FAIL() << "a bad parameter must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("alpha"), std::string::npos) << e.what();
  }
  bad.setParam("shape/alpha", "not a number");
  EXPECT_THROW(loader.load(bad, "world"), std::runtime_error);
  bad.setParam("shape/alpha", 0.01);
  bad.setParam("shape/voxels_per_side", 64.5);
  EXPECT_THROW(loader.load(bad, "world"), std::runtime_error);
  bad.setParam("shape/voxels_per_side", 64);
  bad.setParam("shape/alpah", 0.1);  // misspelt
  try {
    loader.load(bad, "world");
    FAIL() << "an unknown key must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("alpah"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cluster_tolerance"), std::string::npos) << e.what();  // valid keys listed
  }
  bad.deleteParam("shape/alpah");
  bad.setParam("shape/red_min_hue", 40);  // above red_max_hue: no pixel would pass, nothing mapped
  try {
    loader.load(bad, "world");
    FAIL() << "a reversed red band must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("red_max_hue"), std::string::npos) << e.what();
  }
  bad.deleteParam("shape/red_min_hue");
  {  // two estimators of one name would share one namespace
    XmlRpc::XmlRpcValue twice;
    twice[0]["name"] = "shape";
    twice[0]["type"] = "fruit_shape_completion/SuperellipsoidEstimator";
    twice[1]["name"] = "shape";
    twice[1]["type"] = "fruit_shape_completion/SuperellipsoidEstimator";
    ros::NodeHandle two("~/two_alike");
    two.setParam("shape_estimators", twice);
    ros_io::ShapeEstimatorLoader fresh;
    try {
      fresh.load(two, "world");
      FAIL() << "a repeated name must throw";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("repeats the name 'shape'"), std::string::npos) << e.what();
    }
  }
  // Valid for the fit (finite, > 0) but beyond the live range rqt_reconfigure offers, where the
  // live server would clamp it to 10 m without a word.
  bad.setParam("shape/target_view_max_range", 50.0);
  try {
    loader.load(bad, "world");
    FAIL() << "a live setting outside its live range must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("target_view_max_range 50"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("-> 10"), std::string::npos) << e.what();
  }
  bad.deleteParam("shape/target_view_max_range");
  bad.setParam("shape/input_outlier_k", 500);  // within both the statistic's bound and the live range
  EXPECT_NO_THROW(loader.load(bad, "world"));
  bad.deleteParam("shape/input_outlier_k");
  bad.setParam("shape/fruit_cloud_topic", 3);  // a topic must be a string
  try {
    loader.load(bad, "world");
    FAIL() << "a topic of the wrong type must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("fruit_cloud_topic"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("a string"), std::string::npos) << e.what();
  }
}

// fruit_mapping_node's own keys as the node checks them: a misspelt one stops it naming the key.
TEST(FruitMappingNode, AMisspeltKeyOfItsOwnIsNamedWithTheValidOnes) {
  ros::NodeHandle nh("~/node_keys");
  setOneEstimator(nh, "fruits", "fruit_shape_completion/SuperellipsoidEstimator");
  nh.setParam("fruits/alpha", 0.01);
  nh.setParam("tf_wait", 1.0);
  std::vector<std::string> known = {"map_frame", "roi_topic", "tf_wait", "shape_estimators"};
  ros_io::ShapeEstimatorLoader loader;
  loader.load(nh, "world");
  ASSERT_EQ(loader.names(), std::vector<std::string>{"fruits"});
  known.insert(known.end(), loader.names().begin(), loader.names().end());
  EXPECT_NO_THROW(ros_io::rejectUnknownKeys(nh, known));
  nh.setParam("tf_wiat", 2.0);
  try {
    ros_io::rejectUnknownKeys(nh, known);
    FAIL() << "a misspelt key must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("tf_wiat"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("tf_wait"), std::string::npos) << e.what();  // valid keys listed
  }
  nh.deleteParam("tf_wiat");
  // Estimator parameters live in the estimator's namespace, not beside the node's keys.
  nh.setParam("alpha", 0.01);
  EXPECT_THROW(ros_io::rejectUnknownKeys(nh, known), std::runtime_error);
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
  // A repeated coordinate field, or one field carrying three: PCL would leave the missing
  // coordinates at 0 and the points would be mapped onto a plane.
  sensor_msgs::PointCloud2 twice_x = good;
  twice_x.fields[1].name = "x";
  EXPECT_FALSE(ros_io::fromCloud(twice_x, &back, &non_finite, &err));
  EXPECT_NE(err.find("one x, one y and one z"), std::string::npos) << err;
  sensor_msgs::PointCloud2 triple = good;
  triple.fields[0].count = 3;
  EXPECT_FALSE(ros_io::fromCloud(triple, &back, &non_finite, &err));
  EXPECT_NE(err.find("one float32"), std::string::npos) << err;
  sensor_msgs::PointCloud2 big_endian = good;
  big_endian.is_bigendian = true;
  EXPECT_FALSE(ros_io::fromCloud(big_endian, &back, &non_finite, &err));
  EXPECT_NE(err.find("big-endian"), std::string::npos) << err;
}

// The markers and clouds grow with the map (a mesh per fruit, the whole surface): with nobody
// listening nothing is built; the first subscriber gets the latest state, built when it connects.
TEST(FruitPublisher, BuildsMarkersAndCloudsOnlyForTopicsSomeoneListensTo) {
  ros::NodeHandle nh("lazy_publisher");
  ros_io::FruitPublisher publisher(nh, "world", "superellipsoids");
  auto fruit = [](int id, double x) {
    FruitEstimate f;
    f.id = id;
    f.accepted = true;
    f.shape.a = f.shape.b = f.shape.c = 0.04;
    f.shape.t = Eigen::Vector3d(x, 0, 0);
    f.volume = f.shape.volume();
    f.points = PointList{Eigen::Vector3d(x - 0.04, 0, 0), Eigen::Vector3d(x, -0.04, 0)};
    f.missing_surface = PointList{Eigen::Vector3d(x + 0.04, 0, 0)};
    return f;
  };
  std::atomic<int> arrays{0};
  ros::Subscriber se = nh.subscribe<superellipsoid_msgs::SuperellipsoidArray>(
      "superellipsoids", 4, [&](const superellipsoid_msgs::SuperellipsoidArray::ConstPtr&) { ++arrays; });
  ASSERT_TRUE(waitFor([&] { return se.getNumPublishers() > 0; }, 10.0));
  publisher.publish({fruit(1, 0.0)}, PointList{Eigen::Vector3d(0, 0, 0.04)}, ros::Time(1.0));
  publisher.sendVisuals();
  publisher.publish({fruit(1, 0.0), fruit(2, 0.2)}, PointList{Eigen::Vector3d(0, 0, 0.04)}, ros::Time(2.0));
  publisher.sendVisuals();
  ASSERT_TRUE(waitFor([&] { return arrays.load() == 2; }, 10.0));  // the superellipsoids always go out
  EXPECT_EQ(publisher.visualsBuilt(), 0u);

  visualization_msgs::MarkerArray markers;
  int marker_messages = 0;
  ros::Subscriber sub = nh.subscribe<visualization_msgs::MarkerArray>(
      "fruit_markers", 4, [&](const visualization_msgs::MarkerArray::ConstPtr& m) {
        markers = *m;
        ++marker_messages;
      });
  ASSERT_TRUE(waitFor([&] { return marker_messages > 0; }, 10.0));
  ros::WallDuration(0.3).sleep();
  ros::spinOnce();
  EXPECT_EQ(marker_messages, 1);
  ASSERT_EQ(markers.markers.size(), 5u);  // DELETEALL, then a mesh and a label per fruit of the latest state
  EXPECT_EQ(markers.markers[1].header.stamp, ros::Time(2.0));
  EXPECT_EQ(publisher.visualsBuilt(), 1u);  // the markers only: the clouds still have no subscriber

  publisher.publish({fruit(1, 0.0)}, PointList(), ros::Time(3.0));
  ros::WallDuration(0.2).sleep();
  ros::spinOnce();
  EXPECT_EQ(marker_messages, 1);  // kept, not sent: sendVisuals() sends, outside a host's locks
  publisher.sendVisuals();
  ASSERT_TRUE(waitFor([&] { return marker_messages == 2; }, 10.0));
  EXPECT_EQ(markers.markers.size(), 3u);
  EXPECT_EQ(publisher.visualsBuilt(), 2u);
}

TEST(SurfaceCloudNode, SkipsBadCloudsAndFitsGoodOnes) {
  ros::NodeHandle nh;
  ros::Publisher pub = nh.advertise<sensor_msgs::PointCloud2>("/surface_cloud_node/surface_cloud", 1, true);
  superellipsoid_msgs::SuperellipsoidArray last;
  int received = 0;
  ros::Subscriber sub = nh.subscribe<superellipsoid_msgs::SuperellipsoidArray>(
      "/surface_cloud_node/superellipsoids", 5, [&](const superellipsoid_msgs::SuperellipsoidArrayConstPtr& m) {
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
  superellipsoid_msgs::SuperellipsoidArray last;
  std::size_t markers = 0;
  ros::Subscriber sub = nh.subscribe<superellipsoid_msgs::SuperellipsoidArray>(
      "/sim_viewpoint_planner/superellipsoid/superellipsoids", 5,
      [&](const superellipsoid_msgs::SuperellipsoidArrayConstPtr& m) { last = *m; });
  ros::Subscriber msub = nh.subscribe<visualization_msgs::MarkerArray>(
      "/sim_viewpoint_planner/superellipsoid/fruit_markers", 5,
      [&](const visualization_msgs::MarkerArrayConstPtr& m) { markers = m->markers.size(); });
  sim::Scene scene;
  std::string err;
  ASSERT_TRUE(sim::loadSceneSpec("procedural:3", &scene, &err));
  int red = 0;
  const auto truth = sim::computeFruitTruth(scene);
  for (const auto& f : truth) red += f.color == "red";
  ASSERT_TRUE(waitFor([&] { return static_cast<int>(last.superellipsoids.size()) >= red / 2; }, 180.0))
      << "only " << last.superellipsoids.size() << " superellipsoids published for " << red << " red fruits";
  // The first fits of a fruit come from one or two views; judge them a few views later (under
  // a loaded machine the first snapshot held two half-seen fruits below 0.8 accuracy).
  waitFor([&] { return false; }, 5.0);
  ASSERT_GE(static_cast<int>(last.superellipsoids.size()), red / 2);
  EXPECT_GT(markers, last.superellipsoids.size());  // a mesh and a label per fruit
  int good = 0;
  std::ostringstream report;
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
    report << " [" << s.id << ": " << best * 100 << " cm, accuracy " << acc << "]";
  }
  EXPECT_GE(good, static_cast<int>(0.8 * last.superellipsoids.size())) << report.str();
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_ros_integration");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
