#pragma once
// Reads the superellipsoid estimator's parameters (every paper parameter) from a ROS namespace,
// defaults from the core structs (config/shape_estimators.yaml lists them); a parameter of the
// wrong type or value, or a key in the namespace that is neither an estimator parameter nor
// one of `other_keys` (the caller's own), throws std::runtime_error naming it and the valid keys.
#include <fruit_shape_completion/host/superellipsoid_estimator.h>

#include <ros/node_handle.h>

#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace ros_io {

// The plugin's own keys in the same namespace (topics and the camera frame buffer). Nodes that
// share config/shape_estimators.yaml but have no such inputs accept and ignore them.
const std::vector<std::string>& pluginInputKeys();

host::SuperellipsoidEstimatorParams readEstimatorParams(const ros::NodeHandle& nh,
                                                           const std::vector<std::string>& other_keys = {});

// A string parameter, if present; present with another type throws std::runtime_error naming it.
void readStringParam(const ros::NodeHandle& nh, const std::string& name, std::string* value);
void readNumberParam(const ros::NodeHandle& nh, const std::string& name, double* value);
void readIntParam(const ros::NodeHandle& nh, const std::string& name, int* value);

// Throws std::runtime_error naming the first key directly under `nh`'s namespace that is not in
// `known` (a misspelt key would otherwise leave its parameter at the default without a word),
// with the valid keys.
void rejectUnknownKeys(const ros::NodeHandle& nh, const std::vector<std::string>& known);

}  // namespace ros_io
}  // namespace fruit_shape_completion
