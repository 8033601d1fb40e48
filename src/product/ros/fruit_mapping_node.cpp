// fruit_mapping_node: the shape estimators without a planner, on what the upstream pipeline
// publishes (pointcloud_roi_msgs/PointcloudWithRoi on /detect_roi/results, from a live camera
// through pointcloud_roi or from a bag). Hosts the estimators listed in ~shape_estimators exactly
// as the patched roi_viewpoint_planner does (ros_io::RoiPlannerShapeEstimators), so each
// publishes in ~<name>/ and offers clear_map, save_map and load_map there; ~clear_map clears
// them all (upstream calls /voxblox_node/clear_map on reset: remap it here).
#include <fruit_shape_completion/ros/roi_planner_shape_estimators.h>
#include <fruit_shape_completion/ros/upstream_messages.h>

#include <ros/ros.h>
#include <std_srvs/Empty.h>

using namespace fruit_shape_completion;

int main(int argc, char** argv) {
  ros::init(argc, argv, "fruit_mapping_node");
  ros::NodeHandle pnh("~");
  std::string map_frame = "world", roi_topic = ros_io::kUpstreamRoiTopic;
  pnh.param("map_frame", map_frame, map_frame);
  pnh.param("roi_topic", roi_topic, roi_topic);
  std::unique_ptr<ros_io::RoiPlannerShapeEstimators> estimators;
  try {
    estimators = std::make_unique<ros_io::RoiPlannerShapeEstimators>(pnh, map_frame);
  } catch (const std::exception& e) {
    ROS_FATAL("%s", e.what());
    return 1;
  }
  if (estimators->empty()) ROS_WARN("no shape estimators configured in %s/shape_estimators", pnh.getNamespace().c_str());
  ros::Subscriber sub = pnh.subscribe<pointcloud_roi_msgs::PointcloudWithRoi>(
      roi_topic, 2, [&](const pointcloud_roi_msgs::PointcloudWithRoiConstPtr& msg) {
        estimators->insertView(msg->cloud, msg->roi_indices, msg->transform, msg->cloud.header.stamp.toSec());
      });
  ros::ServiceServer clear = pnh.advertiseService<std_srvs::Empty::Request, std_srvs::Empty::Response>(
      "clear_map", [&](std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
        estimators->reset();
        ROS_INFO("fruit maps cleared");
        return true;
      });
  ROS_INFO("fruit_mapping_node: PointcloudWithRoi on %s, map frame %s", pnh.resolveName(roi_topic).c_str(), map_frame.c_str());
  // Views on one thread (in order), services and diagnostics on others, as in the planner.
  ros::AsyncSpinner spinner(2);
  spinner.start();
  ros::waitForShutdown();
  return 0;
}
