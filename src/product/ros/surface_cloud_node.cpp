// surface_cloud_node: clustering and fitting only, for recorded data. Subscribes to a fruit
// surface cloud (~surface_cloud, sensor_msgs/PointCloud2 in any frame with tf, e.g. voxblox's
// surface_pointcloud) and publishes the superellipsoids as superellipsoid_msgs/SuperellipsoidArray
// on ~superellipsoids_topic (default where capsicum_superellipsoid_detector publishes them), and
// fruit_markers, clusters, missing_surface and tsdf_surface in its private namespace, in
// ~map_frame. Usable with rosbag play.
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/ros/estimator_params.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/upstream_messages.h>

#include <ros/ros.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_listener.h>

#include <stdexcept>

using namespace fruit_shape_completion;

int main(int argc, char** argv) {
  ros::init(argc, argv, "surface_cloud_node");
  ros::NodeHandle pnh("~");
  std::string map_frame = "world", superellipsoids_topic = ros_io::kUpstreamSuperellipsoidsTopic;
  std::unique_ptr<FruitShapePipeline> pipeline;
  try {
    // A value of the wrong type stops the node naming it (pnh.param would take the default).
    ros_io::readStringParam(pnh, "map_frame", &map_frame);
    ros_io::readStringParam(pnh, "superellipsoids_topic", &superellipsoids_topic);
    if (map_frame.empty()) throw std::runtime_error("~map_frame must name a frame");
    if (superellipsoids_topic.empty()) throw std::runtime_error("~superellipsoids_topic must name a topic");
    // shape_estimators: the shared config file's list, which names the namespace read here.
    ros_io::rejectUnknownKeys(pnh, {"map_frame", "superellipsoids_topic", "superellipsoid", "shape_estimators"});
    // Fit parameters as for the plugin, from ~superellipsoid/ (config/shape_estimators.yaml); the
    // plugin's input topics there do not apply to a node fed surface clouds.
    pipeline = std::make_unique<FruitShapePipeline>(
        ros_io::readEstimatorParams(ros::NodeHandle(pnh, "superellipsoid"), ros_io::pluginInputKeys()).pipeline);
  } catch (const std::exception& e) {
    ROS_FATAL("%s", e.what());
    return 1;
  }
  ros_io::FruitPublisher publisher(pnh, map_frame, superellipsoids_topic);
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  std::size_t dropped = 0;
  auto on_cloud = [&](const sensor_msgs::PointCloud2ConstPtr& msg) {
    PointList pts;
    std::size_t bad = 0;
    std::string err;
    if (!ros_io::fromCloud(*msg, &pts, &bad, &err)) {
      ROS_WARN("surface cloud skipped: %s", err.c_str());
      return;
    }
    if (bad > 0) ROS_WARN("surface cloud: %zu NaN/Inf points skipped", bad);
    if (pts.empty()) {
      ROS_WARN("surface cloud skipped: no finite points");
      return;
    }
    if (!msg->header.frame_id.empty() && msg->header.frame_id != map_frame) {
      try {
        const Eigen::Isometry3d T = tf2::transformToEigen(
            buffer.lookupTransform(map_frame, msg->header.frame_id, msg->header.stamp, ros::Duration(0.2)));
        for (auto& p : pts) p = T * p;
      } catch (const tf2::TransformException& e) {
        ROS_WARN("surface cloud skipped: no transform to %s (%s)", map_frame.c_str(), e.what());
        return;
      }
    }
    const auto& fruits = pipeline->update(pts);
    const std::size_t points = pts.size();
    publisher.publish(fruits, std::move(pts), msg->header.stamp);
    publisher.sendVisuals();
    ROS_INFO("surface cloud: %zu points, %d clusters, %d fruits accepted (%.1f ms)", points,
             pipeline->lastStats().clusters, pipeline->lastStats().accepted, pipeline->lastStats().seconds * 1000);
  };
  ros::Subscriber sub = pnh.subscribe<sensor_msgs::PointCloud2>("surface_cloud", 2, [&](const sensor_msgs::PointCloud2ConstPtr& msg) {
    try {
      on_cloud(msg);
    } catch (const std::exception& e) {  // std::bad_alloc among them: drop this cloud, keep running
      ROS_ERROR("surface cloud dropped (%zu so far): %s", ++dropped, e.what());
    }
  });
  ros::spin();
  return 0;
}
