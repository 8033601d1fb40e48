// sim_planner_node (node name sim_viewpoint_planner, so it cannot clash with upstream's
// roi_viewpoint_planner): runs the package's viewpoint planner on a
// simulated scene and hosts the shape-estimator plugins listed in ~shape_estimators. Publishes
// the camera on tf (map frame -> camera), the ROI octree (~roi_octree) and the Old boxes
// (~old_boxes) as markers, and the last full cloud (~scene_cloud). With ~live:=true it instead
// takes fruit clouds (sensor_msgs/PointCloud2 on ~fruit_cloud) with the sensor pose from tf.
// With ~publish_sensors:=true it also publishes, per view, what a robot's stack publishes: the
// organized camera cloud (~camera_cloud_topic, as depth_image_proc), tf at its stamp, and
// pointcloud_roi's PointcloudWithRoi (~roi_topic), so planner hosts in other processes (the
// patched planner, fruit_mapping_node) get the episode through subscriptions; ~episode_done
// (latched) carries the number of views when the episode has ended.
#include <fruit_shape_completion/instrument/planner/pointcloud_roi.h>
#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>
#include <fruit_shape_completion/ros/camera_frames.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/shape_estimator_loader.h>
#include <fruit_shape_completion/ros/upstream_messages.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>

#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <std_msgs/UInt32.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <atomic>
#include <mutex>

using namespace fruit_shape_completion;

namespace {

visualization_msgs::MarkerArray octreeMarkers(const planner::RoiOcTree& tree, const std::string& frame) {
  visualization_msgs::MarkerArray arr;
  visualization_msgs::Marker occ, roi;
  for (auto* m : {&occ, &roi}) {
    m->header.frame_id = frame;
    m->header.stamp = ros::Time::now();
    m->type = visualization_msgs::Marker::CUBE_LIST;
    m->pose.orientation.w = 1;
    m->scale.x = m->scale.y = m->scale.z = tree.getResolution();
    m->color.a = 1.0f;
  }
  occ.ns = "occupied";
  occ.color.r = occ.color.g = occ.color.b = 0.6f;
  occ.color.a = 0.25f;
  roi.ns = "roi";
  roi.id = 1;
  roi.color.r = 1.0f;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    geometry_msgs::Point p;
    p.x = it.getX();
    p.y = it.getY();
    p.z = it.getZ();
    (tree.isRoi(&*it) ? roi : occ).points.push_back(p);
  }
  arr.markers = {occ, roi};
  return arr;
}

visualization_msgs::MarkerArray boxMarkers(const std::vector<planner::RoiCluster>& clusters, const std::string& frame) {
  visualization_msgs::MarkerArray arr;
  visualization_msgs::Marker clear;
  clear.action = visualization_msgs::Marker::DELETEALL;
  arr.markers.push_back(clear);
  int id = 0;
  for (const auto& c : clusters) {
    visualization_msgs::Marker m;
    m.header.frame_id = frame;
    m.header.stamp = ros::Time::now();
    m.ns = "old_boxes";
    m.id = id++;
    m.type = visualization_msgs::Marker::CUBE;
    const Eigen::Vector3d ctr = c.center(), size = c.box_max - c.box_min;
    m.pose.position.x = ctr.x();
    m.pose.position.y = ctr.y();
    m.pose.position.z = ctr.z();
    m.pose.orientation.w = 1;
    m.scale.x = std::max(size.x(), 1e-3);
    m.scale.y = std::max(size.y(), 1e-3);
    m.scale.z = std::max(size.z(), 1e-3);
    m.color.b = 1.0f;
    m.color.a = 0.3f;
    arr.markers.push_back(m);
  }
  return arr;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "sim_viewpoint_planner");
  ros::NodeHandle pnh("~");
  std::string map_frame = "world", scene_spec = "procedural", sensor_frame = "camera";
  double duration = 180.0, realtime_factor = 0.0;
  int seed = 1;
  bool shape_targets = true, live = false, exit_when_done = false, publish_sensors = false;
  std::string input_name = "camera", camera_topic = "/camera/depth/points", roi_topic = ros_io::kUpstreamRoiTopic;
  pnh.param("map_frame", map_frame, map_frame);
  pnh.param("scene", scene_spec, scene_spec);
  pnh.param("duration", duration, duration);
  pnh.param("seed", seed, seed);
  pnh.param("shape_targets", shape_targets, shape_targets);
  pnh.param("realtime_factor", realtime_factor, realtime_factor);
  pnh.param("live", live, live);
  pnh.param("sensor_frame", sensor_frame, sensor_frame);
  pnh.param("exit_when_done", exit_when_done, exit_when_done);
  pnh.param("input", input_name, input_name);
  pnh.param("publish_sensors", publish_sensors, publish_sensors);
  pnh.param("camera_cloud_topic", camera_topic, camera_topic);
  pnh.param("roi_topic", roi_topic, roi_topic);
  planner::PlannerParams::Input input = planner::PlannerParams::Input::kCamera;
  if (!planner::parseInput(input_name, &input)) {
    ROS_FATAL("~input must be camera, roi or fruit-cloud, not '%s'", input_name.c_str());
    return 1;
  }
  std::string profile = "paper";
  pnh.param("profile", profile, profile);
  if (profile != "paper" && profile != "ideal") {
    ROS_FATAL("~profile must be paper or ideal, not '%s'", profile.c_str());
    return 1;
  }

  ros_io::ShapeEstimatorLoader loader;
  host::ShapeEstimatorHost& host = loader.host();
  try {
    loader.load(pnh, map_frame);
  } catch (const std::exception& e) {
    ROS_FATAL("%s", e.what());
    return 1;
  }

  if (live) {
    tf2_ros::Buffer buffer;
    tf2_ros::TransformListener listener(buffer);
    std::mutex mutex;  // views arrive on callback threads; the host is shared with the planner
    const PointList none;
    std::atomic<std::size_t> dropped{0};
    ros::Subscriber sub = pnh.subscribe<sensor_msgs::PointCloud2>("fruit_cloud", 2, [&](const sensor_msgs::PointCloud2ConstPtr& msg) {
      try {
        PointList pts;
        std::size_t bad = 0;
        std::string err;
        if (!ros_io::fromCloud(*msg, &pts, &bad, &err)) {
          const std::size_t n = ++dropped;  // outside the macro: a throttled log evaluates its arguments only when it prints
          ROS_WARN_THROTTLE(5.0, "fruit_cloud skipped (%zu so far): %s", n, err.c_str());
          return;
        }
        if (msg->header.frame_id.empty()) {
          const std::size_t n = ++dropped;
          ROS_WARN_THROTTLE(5.0, "fruit_cloud skipped (%zu so far): the cloud has no frame_id", n);
          return;
        }
        geometry_msgs::TransformStamped to_map, sensor;
        try {
          to_map = buffer.lookupTransform(map_frame, msg->header.frame_id, msg->header.stamp, ros::Duration(0.2));
          sensor = buffer.lookupTransform(map_frame, sensor_frame, msg->header.stamp, ros::Duration(0.2));
        } catch (const tf2::TransformException& e) {
          const std::size_t n = ++dropped;
          ROS_WARN_THROTTLE(5.0, "fruit_cloud skipped (%zu so far): no transform (%s)", n, e.what());
          return;
        }
        const Eigen::Isometry3d T = tf2::transformToEigen(to_map);
        for (auto& p : pts) p = T * p;
        std::lock_guard<std::mutex> lock(mutex);
        host.onView(host::ViewData{pts, none, tf2::transformToEigen(sensor), msg->header.stamp.toSec(),
                                      host::ViewSource::kFruitCloud});
      } catch (const std::exception& e) {  // std::bad_alloc included: drop this cloud, keep running
        const std::size_t n = ++dropped;
        ROS_WARN_THROTTLE(5.0, "fruit_cloud dropped (%zu so far): %s", n, e.what());
      }
    });
    ros::AsyncSpinner spinner(2);
    spinner.start();
    ros::waitForShutdown();
    return 0;
  }

  sim::Scene scene;
  std::string err;
  if (!sim::loadSceneSpec(scene_spec, &scene, &err)) {
    ROS_FATAL("%s", err.c_str());
    return 1;
  }
  std::vector<int> triangle_fruit;
  const planner::SceneTruth truth = planner::makeSceneTruth(sim::computeFruitTruth(scene, &triangle_fruit), planner::PlannerParams().octree_resolution);
  planner::PlannerParams params;
  if (profile == "paper") params = planner::paperProfile(params);
  sim::Shading shading;
  shading.textures = params.textures;
  const sim::RgbdRenderer renderer(scene, triangle_fruit, shading);
  tf2_ros::TransformBroadcaster tf;
  ros::Publisher octree_pub = pnh.advertise<visualization_msgs::MarkerArray>("roi_octree", 1, true);
  ros::Publisher boxes_pub = pnh.advertise<visualization_msgs::MarkerArray>("old_boxes", 1, true);
  ros::Publisher cloud_pub = pnh.advertise<sensor_msgs::PointCloud2>("scene_cloud", 1, true);
  params.duration = duration;
  params.seed = static_cast<unsigned>(seed);
  params.shape_targets = shape_targets;
  params.render_threads = 2;
  params.input = input;
  // Upstream's plan_with_trolley names (Planner.cfg), in metres and seconds: 0 m, no trolley.
  pnh.param("trolley_move_length", params.trolley_move_length, params.trolley_move_length);
  pnh.param("trolley_time_per_segment", params.trolley_time_per_segment, params.trolley_time_per_segment);
  sim::RedThreshold red_test;  // pointcloud_roi's colour test, as the episode's profile has it
  if (params.upstream_red_test) red_test.test = sim::RedThreshold::Test::kUpstream;
  ros::Publisher camera_pub, roi_pub, done_pub = pnh.advertise<std_msgs::UInt32>("episode_done", 1, true);
  if (publish_sensors) {
    camera_pub = pnh.advertise<sensor_msgs::PointCloud2>(camera_topic, 2);
    roi_pub = pnh.advertise<pointcloud_roi_msgs::PointcloudWithRoi>(roi_topic, 2);
    // A robot's camera streams before the planner's first view; here the first view is the
    // first frame, so give subscribers a moment to connect to both topics.
    const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(10.0);
    while (ros::ok() && ros::WallTime::now() < until &&
           (camera_pub.getNumSubscribers() == 0 || roi_pub.getNumSubscribers() == 0))
      ros::WallDuration(0.05).sleep();
  }
  ROS_INFO("planning on %s (%zu red ground-truth fruits scored) for %.0f s", scene.name.c_str(), truth.enclosed.size(), duration);
  const auto result = planner::runEpisode(scene, renderer, truth, host, params,
      [&](const planner::ViewRecord& v, const planner::RoiOcTree& tree, const sim::RgbdFrame& frame, const host::ViewData&) {
        // The camera on tf at the frame's stamp: z forward, as the organized cloud's points.
        const ros::Time stamp = ros::Time::now();
        geometry_msgs::TransformStamped t = tf2::eigenToTransform(sim::cameraPose(frame.camera));
        t.header.stamp = stamp;
        t.header.frame_id = map_frame;
        t.child_frame_id = sensor_frame;
        tf.sendTransform(t);
        if (publish_sensors) {
          camera_pub.publish(ros_io::toOrganizedCloud(sim::organizedFrame(frame), sensor_frame, stamp));
          // pointcloud_roi publishes after its own processing of the same frame.
          const planner::RoiCloud roi = planner::pointcloudRoi(frame, params.roi_leaf, red_test);
          pointcloud_roi_msgs::PointcloudWithRoi msg;
          msg.cloud = ros_io::toCloud(roi.points, map_frame, stamp, roi.colours);
          msg.roi_indices = roi.roi_indices;
          msg.transform = t.transform;
          roi_pub.publish(msg);
        }
        octree_pub.publish(octreeMarkers(tree, map_frame));
        boxes_pub.publish(boxMarkers(tree.roiClusters(10), map_frame));
        cloud_pub.publish(ros_io::toCloud(sim::cloudsFromFrame(frame, {}).full, map_frame, ros::Time::now()));
        ROS_INFO("view %d at %.0f s: Old MA50 %d fruits, SE MA50 %d fruits (accuracy %.3f, centre %.2f cm)", v.view,
                 v.time, v.old_true.ma50.fruits, v.se_true.ma50.fruits, v.se_true.ma50.accuracy,
                 v.se_true.ma50.center_error_cm);
        if (realtime_factor > 0) ros::Duration(params.view_cost / realtime_factor).sleep();
        ros::spinOnce();
        return ros::ok();
      });
  if (!result.message.empty()) ROS_WARN("%s", result.message.c_str());
  if (result.dropped_views > 0)
    ROS_WARN("%d views dropped, the first: %s", result.dropped_views, result.dropped_reason.c_str());
  ROS_INFO("episode done: %zu views", result.views.size());
  std_msgs::UInt32 done;
  done.data = static_cast<std::uint32_t>(result.views.size());
  done_pub.publish(done);
  if (!exit_when_done) ros::spin();
  return 0;
}
