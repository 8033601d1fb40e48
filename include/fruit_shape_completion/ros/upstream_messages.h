#pragma once
// The upstream pipeline's messages (from their own packages, superellipsoid_msgs and
// pointcloud_roi_msgs: integration/upstream.repos) and where the upstream nodes expect them.
#include <pointcloud_roi_msgs/PointcloudWithRoi.h>
#include <superellipsoid_msgs/SuperellipsoidArray.h>

namespace fruit_shape_completion {
namespace ros_io {

// Where rvp_evaluation's ExternalClusterEvaluator listens, and where pointcloud_roi publishes.
constexpr char kUpstreamSuperellipsoidsTopic[] = "/capsicum_superellipsoid_detector/superellipsoids";
constexpr char kUpstreamRoiTopic[] = "/detect_roi/results";

}  // namespace ros_io
}  // namespace fruit_shape_completion
