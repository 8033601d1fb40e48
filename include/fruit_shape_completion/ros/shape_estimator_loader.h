#pragma once
// The planner side of the plugin seam: reads the planner's `shape_estimators` parameter, e.g.
//   shape_estimators: [{name: superellipsoid, type: fruit_shape_completion/SuperellipsoidEstimator}]
// loads each with pluginlib, initialises it in <planner namespace>/<name>, and adds it to the
// host::ShapeEstimatorHost it owns. The upstream roi_viewpoint_planner needs only this and the
// host: after its scan insertion: host().onView(view); before its ROI sampling: host().extraTargets().
// Publishes each estimator's diagnostics (/diagnostics, once a second): error if disabled.
#include <fruit_shape_completion/host/shape_estimator.h>
#include <fruit_shape_completion/shape_estimator_plugin.h>

#include <diagnostic_updater/diagnostic_updater.h>
#include <pluginlib/class_loader.hpp>
#include <ros/timer.h>

#include <atomic>
#include <cstddef>
#include <memory>

namespace fruit_shape_completion {
namespace ros_io {

// PointcloudWithRoi input that never reached the estimators: RoiPlannerShapeEstimators counts,
// the loader publishes (one status for all estimators) where load() is asked to.
struct PlannerViewDrops {
  std::atomic<std::size_t> views{0};    // malformed PointcloudWithRoi, or dropped (out of memory)
  std::atomic<std::size_t> indices{0};  // ROI indices out of range or on non-finite points
  std::atomic<std::size_t> before_reset{0};  // views the host's map took before a reset came (not mapped)
};

class ShapeEstimatorLoader {
 public:
  ShapeEstimatorLoader();
  // Throws std::runtime_error with a clear message for a malformed list, an unknown plugin
  // type or a plugin that refuses its parameters.
  // With report_view_drops, /diagnostics also carries plannerViewDrops() as its own status.
  void load(ros::NodeHandle& planner_nh, const std::string& map_frame, bool report_view_drops = false);
  host::ShapeEstimatorHost& host() { return host_; }
  const host::ShapeEstimatorHost& host() const { return host_; }
  // The loaded estimators' names as the list gives them: each owns the namespace of its name.
  const std::vector<std::string>& names() const { return names_; }
  PlannerViewDrops& plannerViewDrops() { return planner_drops_; }
  const PlannerViewDrops& plannerViewDrops() const { return planner_drops_; }

 private:
  // Order matters: members are destroyed in reverse, so the plugins (in host_) are destroyed
  // before the class loader unloads their libraries. Owning the host makes that impossible to get
  // wrong from outside.
  void diagnose(std::size_t i, diagnostic_updater::DiagnosticStatusWrapper& status) const;

  PlannerViewDrops planner_drops_;  // before the timer that reads them, so destroyed after it
  pluginlib::ClassLoader<ShapeEstimatorPlugin> loader_;
  host::ShapeEstimatorHost host_;
  std::vector<ShapeEstimatorPlugin*> plugins_;  // owned by host_, same order
  std::vector<std::string> names_;              // same order
  std::unique_ptr<diagnostic_updater::Updater> diagnostics_;
  ros::Timer diagnostics_timer_;
};

}  // namespace ros_io
}  // namespace fruit_shape_completion
