#pragma once
// Reads the superellipsoid estimator's parameters (every paper parameter) from a ROS namespace,
// defaults from the core structs (config/shape_estimators.yaml lists them); a parameter of the
// wrong type or value throws std::runtime_error naming it.
#include <fruit_shape_completion/planner/superellipsoid_estimator.h>

#include <ros/node_handle.h>

namespace fruit_shape_completion {
namespace ros_io {

planner::SuperellipsoidEstimatorParams readEstimatorParams(const ros::NodeHandle& nh);

}  // namespace ros_io
}  // namespace fruit_shape_completion
