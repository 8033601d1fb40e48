// fruit_mapping_node: the shape estimators without a planner, on what the upstream pipeline
// publishes (pointcloud_roi_msgs/PointcloudWithRoi on /detect_roi/results, from a live camera
// through pointcloud_roi or from a bag). Hosts the estimators listed in ~shape_estimators exactly
// as the patched roi_viewpoint_planner does (ros_io::RoiPlannerShapeEstimators), so each
// publishes in ~<name>/ and offers clear_map, save_map and load_map there; ~clear_map clears
// them all (upstream calls /voxblox_node/clear_map on reset: remap it here). A cloud in the map
// frame comes with its sensor pose in the message; any other cloud is taken to the map frame by
// tf at its stamp, its message's transform read as the sensor's pose in the cloud's frame (as
// pointcloud_roi writes it; identity for a cloud in the camera frame), or skipped and counted.
#include <fruit_shape_completion/ros/estimator_params.h>
#include <fruit_shape_completion/ros/roi_planner_shape_estimators.h>
#include <fruit_shape_completion/ros/upstream_messages.h>

#include <ros/ros.h>
#include <std_srvs/Empty.h>
#include <tf2_ros/transform_listener.h>

#include <stdexcept>

using namespace fruit_shape_completion;

int main(int argc, char** argv) {
  ros::init(argc, argv, "fruit_mapping_node");
  ros::NodeHandle pnh("~");
  std::string map_frame = "world", roi_topic = ros_io::kUpstreamRoiTopic;
  double tf_wait = 0.2;  // [s] how long a cloud outside the map frame waits for its transform
  std::unique_ptr<ros_io::RoiPlannerShapeEstimators> estimators;
  try {
    // A value of the wrong type stops the node naming it (pnh.param would take the default).
    ros_io::readStringParam(pnh, "map_frame", &map_frame);
    ros_io::readStringParam(pnh, "roi_topic", &roi_topic);
    ros_io::readNumberParam(pnh, "tf_wait", &tf_wait);
    if (map_frame.empty()) throw std::runtime_error("~map_frame must name a frame");
    if (roi_topic.empty()) throw std::runtime_error("~roi_topic must name a topic");
    if (!(tf_wait >= 0.0 && tf_wait <= 10.0)) throw std::runtime_error("~tf_wait must be in [0, 10] s, not " + std::to_string(tf_wait));
    estimators = std::make_unique<ros_io::RoiPlannerShapeEstimators>(pnh, map_frame);
    // diagnostic_period: diagnostic_updater reads it from the same namespace; each estimator
    // owns the namespace of its name.
    std::vector<std::string> known = {"map_frame", "roi_topic", "tf_wait", "shape_estimators", "diagnostic_period"};
    known.insert(known.end(), estimators->estimatorNames().begin(), estimators->estimatorNames().end());
    ros_io::rejectUnknownKeys(pnh, known);
  } catch (const std::exception& e) {
    ROS_FATAL("%s", e.what());
    return 1;
  }
  if (estimators->empty()) ROS_WARN("no shape estimators configured in %s/shape_estimators", pnh.getNamespace().c_str());
  tf2_ros::Buffer tf_buffer;
  tf2_ros::TransformListener tf_listener(tf_buffer);
  ros::Subscriber sub = pnh.subscribe<pointcloud_roi_msgs::PointcloudWithRoi>(
      roi_topic, 2, [&](const pointcloud_roi_msgs::PointcloudWithRoiConstPtr& msg) {
        const auto& header = msg->cloud.header;
        if (header.frame_id == map_frame) {
          estimators->insertView(msg->cloud, msg->roi_indices, msg->transform, header.stamp.toSec());
          return;
        }
        geometry_msgs::Transform to_map;
        try {
          to_map = tf_buffer.lookupTransform(map_frame, header.frame_id, header.stamp, ros::Duration(tf_wait)).transform;
        } catch (const tf2::TransformException& e) {
          estimators->skipView("no transform from " + header.frame_id + " to " + map_frame + ": " + e.what());
          return;
        }
        estimators->insertView(msg->cloud, msg->roi_indices, msg->transform, header.stamp.toSec(), &to_map);
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
