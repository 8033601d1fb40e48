#pragma once
// The pluginlib base class of shape estimators, loaded by the planner by type name, e.g.
//   shape_estimators: [{name: superellipsoid, type: fruit_shape_completion/SuperellipsoidEstimator}]
// It adds ROS initialisation to host::ShapeEstimator (insert view, update, fruits, extra
// targets, reset).
#include <fruit_shape_completion/host/shape_estimator.h>

#include <ros/node_handle.h>

#include <string>
#include <utility>
#include <vector>

namespace fruit_shape_completion {

class ShapeEstimatorPlugin : public host::ShapeEstimator {
 public:
  // `nh` is the plugin's own namespace (e.g. /roi_viewpoint_planner/superellipsoid): parameters
  // are read and topics advertised there. Throws std::runtime_error naming a bad parameter.
  virtual void initialize(const std::string& name, ros::NodeHandle& nh, const std::string& map_frame) = 0;
  // Name/value pairs the host publishes as the estimator's diagnostics (map size, memory,
  // dropped data, last update).
  virtual std::vector<std::pair<std::string, std::string>> diagnostics() const { return {}; }
  // Non-empty while input is being lost (refused, skipped, over the map's budget) since the last
  // reset: the host's diagnostics turn WARN with it, not only the log.
  virtual std::string diagnosticsWarning() const { return {}; }
};

}  // namespace fruit_shape_completion
