#pragma once
// The upstream pipeline's message types on the wire without depending on their packages (one
// catkin package cannot also be superellipsoid_msgs or pointcloud_roi_msgs): this package
// generates messages laid out field for field as theirs, so the md5sums are equal, and
// advertises or subscribes them under the upstream type names and definitions. Peers built
// against the upstream packages (rvp_evaluation, pointcloud_roi, rosbag) see the upstream types.
#include <fruit_shape_completion/PointcloudWithRoi.h>
#include <fruit_shape_completion/SuperellipsoidArray.h>

#include <boost/function.hpp>
#include <ros/node_handle.h>

#include <string>

namespace fruit_shape_completion {
namespace ros_io {

constexpr char kUpstreamSuperellipsoidArrayType[] = "superellipsoid_msgs/SuperellipsoidArray";
constexpr char kUpstreamPointcloudWithRoiType[] = "pointcloud_roi_msgs/PointcloudWithRoi";
// Where rvp_evaluation's ExternalClusterEvaluator listens, and where pointcloud_roi publishes.
constexpr char kUpstreamSuperellipsoidsTopic[] = "/capsicum_superellipsoid_detector/superellipsoids";
constexpr char kUpstreamRoiTopic[] = "/detect_roi/results";

// Full message definitions (as in a connection header) with the upstream type names.
std::string upstreamSuperellipsoidArrayDefinition();
std::string upstreamPointcloudWithRoiDefinition();

// A publisher of fruit_shape_completion::SuperellipsoidArray advertised as
// superellipsoid_msgs/SuperellipsoidArray.
ros::Publisher advertiseUpstreamSuperellipsoids(ros::NodeHandle& nh, const std::string& topic, bool latch);

// A publisher of fruit_shape_completion::PointcloudWithRoi advertised as
// pointcloud_roi_msgs/PointcloudWithRoi (what pointcloud_roi publishes).
ros::Publisher advertiseUpstreamPointcloudWithRoi(ros::NodeHandle& nh, const std::string& topic, std::uint32_t queue_size);

// A subscriber to pointcloud_roi_msgs/PointcloudWithRoi delivering this package's twin type.
ros::Subscriber subscribeUpstreamPointcloudWithRoi(
    ros::NodeHandle& nh, const std::string& topic, std::uint32_t queue_size,
    const boost::function<void(const fruit_shape_completion::PointcloudWithRoiConstPtr&)>& callback);

}  // namespace ros_io
}  // namespace fruit_shape_completion
