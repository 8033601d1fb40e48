#pragma once
// Publishes a shape estimator's state: the superellipsoids as superellipsoid_msgs/
// SuperellipsoidArray on the given topic (relative names resolve in the namespace), and in the
// namespace fruit_markers (visualization_msgs/MarkerArray: each fit as a triangle mesh plus an
// id/volume label), clusters (PointCloud2 coloured per fruit), missing_surface and tsdf_surface
// (PointCloud2), all in the map frame and latched.
#include <fruit_shape_completion/fruit_estimate.h>
#include <fruit_shape_completion/surface_blocks.h>

#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <sensor_msgs/PointCloud2.h>

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace ros_io {

// An xyz (+ optional packed rgb) PointCloud2.
sensor_msgs::PointCloud2 toCloud(const PointList& points, const std::string& frame, const ros::Time& stamp,
                                 const std::vector<std::array<std::uint8_t, 3>>& colors = {});
// Finite points of an xyz PointCloud2 (float32 x, y, z fields, as PCL and the upstream pipeline send); `non_finite` counts
// the skipped ones. False with a message if the cloud has no x, y, z fields or is malformed.
bool fromCloud(const sensor_msgs::PointCloud2& msg, PointList* points, std::size_t* non_finite, std::string* error);
// A cloud with ROI indices (as in pointcloud_roi_msgs/PointcloudWithRoi): `all` its finite points,
// `selected` the finite points at the indices; `bad_indices` counts indices out of range or on
// non-finite points. False with a message if the cloud is malformed.
bool fromRoiCloud(const sensor_msgs::PointCloud2& msg, const std::vector<std::int32_t>& indices, PointList* all,
                  PointList* selected, std::size_t* bad_indices, std::string* error);

// The superellipsoids go out with every publish(). The markers and point clouds, which grow with
// the map (a mesh per fruit, the whole surface), are built only for topics someone subscribes
// to: at publish() if a subscriber is connected, else when the first one connects (on the ROS
// callback thread that reports it), from the latest state, which is kept (its points shared
// with the estimator's results). A planner run without rviz builds none of them.
class FruitPublisher {
 public:
  FruitPublisher(ros::NodeHandle& nh, const std::string& map_frame, const std::string& superellipsoids_topic);
  // Sends the superellipsoids and keeps the state for the markers and clouds (cheap); then
  // sendVisuals() builds and sends those with a subscriber, from the latest state kept. A host
  // that orders publish() with a reset under a lock calls sendVisuals() outside it.
  void publish(std::vector<FruitEstimate> fruits, SurfaceBlocks surface, const ros::Time& stamp);
  void publish(std::vector<FruitEstimate> fruits, PointList surface, const ros::Time& stamp);
  void sendVisuals();
  // Marker and point cloud messages sent so far.
  std::size_t visualsBuilt() const;

 private:
  struct Visuals;  // the latest state and the topics built from it, shared with connect callbacks
  ros::Publisher superellipsoids_;
  std::shared_ptr<Visuals> visuals_;
};

}  // namespace ros_io
}  // namespace fruit_shape_completion
