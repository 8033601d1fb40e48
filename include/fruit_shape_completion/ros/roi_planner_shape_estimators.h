#pragma once
// The glue for github.com/Eruvae/roi_viewpoint_planner: shape estimators fed with exactly what
// ViewpointPlanner::registerPointcloudWithRoi holds (the PointcloudWithRoi's cloud, ROI
// indices and transform) and returning their extra targets as octomap points, so that the
// planner's patch (integration/roi_viewpoint_planner.patch) stays a few lines.
#include <fruit_shape_completion/ros/shape_estimator_loader.h>
#include <fruit_shape_completion/shape_view_gain.h>

#include <geometry_msgs/Transform.h>
#include <ros/console.h>
#include <octomap/octomap_types.h>
#include <sensor_msgs/PointCloud2.h>

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <shared_mutex>
#include <cstdint>
#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace ros_io {

// A PointcloudWithRoi's view in the map frame. As upstream: if cloud.header.frame_id is the map
// frame, the points are in the map frame and `transform` is the sensor pose; otherwise
// `transform` takes the cloud to the map. With `cloud_to_map` (a host that looks the cloud's frame
// up itself) the points go through it and `transform` is read as pointcloud_roi writes it, the
// sensor's pose in the cloud's frame (identity for a cloud in the camera frame). False with a
// message for a malformed cloud or a non-finite transform; `bad_indices` counts indices out of
// range or on NaN points.
struct RoiView {
  PointList fruit, all;
  Eigen::Isometry3d sensor_pose = Eigen::Isometry3d::Identity();
  std::size_t bad_indices = 0;
};
bool toRoiView(const sensor_msgs::PointCloud2& cloud, const std::vector<std::int32_t>& roi_indices,
               const geometry_msgs::Transform& transform, const std::string& map_frame, RoiView* view,
               std::string* error, const geometry_msgs::Transform* cloud_to_map = nullptr);

// One planning round's shape targets in the planner's types (the patch adds `points` to the ROI
// contour sampler's pool; `directions` as extraTargets gives them) and what a sampled view gains
// from the predicted surface it would see.
class ShapeTargetRound {
 public:
  ShapeTargetRound() = default;
  explicit ShapeTargetRound(std::shared_ptr<const ShapeTargets> targets);
  std::vector<octomap::point3d> points, directions;
  // To add to the view's utility: the predicted surface a camera at `origin` looking along `dir`
  // sees, lines of sight checked in `tree` (the planner's occupancy tree, its lock held). 0
  // unless target_view_gain > 0, 0 for a camera within target_view_clearance of an occupied cell
  // of `tree`, and 0 with a warning if it cannot be computed (out of memory):
  // it runs on the planner's planning thread, which nothing may take down.
  template <typename OccupancyTree>
  double viewGain(const octomap::point3d& origin, const octomap::point3d& dir, const OccupancyTree& tree) const {
    if (!targets_ || targets_->gains.empty()) return 0.0;
    try {
      return shapeViewGain(*targets_, Eigen::Vector3d(origin.x(), origin.y(), origin.z()),
                           Eigen::Vector3d(dir.x(), dir.y(), dir.z()), occupiedCellsBlock(tree),
                           occupiedCellsNear(tree));
    } catch (const std::exception& e) {
      ROS_WARN_THROTTLE(10.0, "shape target view gain not computed (%s): the view is scored without it", e.what());
      return 0.0;
    }
  }

 private:
  std::shared_ptr<const ShapeTargets> targets_;
};

class RoiPlannerShapeEstimators {
 public:
  // Loads the estimators listed in `shape_estimators` of planner_nh, each initialised in
  // planner_nh/<name>. Without the parameter there are none and every call does nothing.
  // Throws std::runtime_error naming a bad entry or parameter.
  RoiPlannerShapeEstimators(ros::NodeHandle& planner_nh, const std::string& map_frame);
  // Waits for insertView calls still running (warning every few seconds while one does):
  // upstream's planner deletes itself while its spinner may still be in a view callback, and a
  // call here can wait for the map a fit is being integrated into; the estimators must outlive it.
  ~RoiPlannerShapeEstimators();
  bool empty() const { return loader_.host().size() == 0; }

  // One view (read as toRoiView reads it). Returns once every estimator has it in its map; the
  // fits run on the estimators' own threads, views arriving meanwhile coalesce into the next
  // fit. Never throws: a malformed cloud or bad indices are logged, counted and skipped.
  // `resets_seen`: resets() read when the host's own map took the view, under the lock its reset
  // holds too; a reset since then makes the view one of the old map's, not mapped (counted).
  void insertView(const sensor_msgs::PointCloud2& cloud, const std::vector<std::int32_t>& roi_indices,
                  const geometry_msgs::Transform& transform, double time = 0.0,
                  const geometry_msgs::Transform* cloud_to_map = nullptr, const std::uint64_t* resets_seen = nullptr);
  // A view its host could not hand over (no transform to the map frame, say): counted and
  // warned as the views insertView skips.
  void skipView(const std::string& why);
  // The estimators' predicted, unseen fruit surface in the map frame, from their latest
  // finished fits. Does not wait for a fit.
  std::vector<octomap::point3d> extraTargets() const;
  // The same, with one direction per target to view it from (the predicted surface's outward
  // normal; zero: any side) in *directions.
  std::vector<octomap::point3d> extraTargets(std::vector<octomap::point3d>* directions) const;
  // The same with the view gain, for one round of sampling.
  ShapeTargetRound targetRound() const;
  // Until no fit is pending or running (false after `seconds`): for tools and tests, which
  // want the fit of the view they just gave; a planner does not wait.
  bool waitForFits(double seconds) const { return loader_.host().waitForUpdates(seconds); }
  // Clears every estimator's map. Waits up to 2 s for insertView calls running (a view is in the
  // old map or the new one, never half; longer only if a tf wait hangs on a paused /clock, and
  // the host's lock must not be held that long); call it where the host clears its own map,
  // under the same lock.
  void reset();
  // Resets so far: a view's ticket (insertView's resets_seen).
  std::uint64_t resets() const { return resets_.load(); }

  host::ShapeEstimatorHost& host() { return loader_.host(); }
  const std::vector<std::string>& estimatorNames() const { return loader_.names(); }
  // Also in /diagnostics ("shape estimators: PointcloudWithRoi input"); restart with reset().
  std::size_t viewsSkipped() const { return loader_.plannerViewDrops().views; }
  std::size_t indicesSkipped() const { return loader_.plannerViewDrops().indices; }  // out of range or non-finite points
  std::size_t viewsFromBeforeAReset() const { return loader_.plannerViewDrops().before_reset; }

 private:
  ShapeEstimatorLoader loader_;
  std::string map_frame_;
  std::atomic<bool> closing_{false};
  std::mutex calls_mutex_;
  std::condition_variable calls_done_;
  int calls_ = 0;  // insertView calls running; guarded by calls_mutex_
  std::shared_timed_mutex reset_mutex_;  // insertView shared, reset() exclusive
  std::atomic<std::uint64_t> resets_{0};
};

}  // namespace ros_io
}  // namespace fruit_shape_completion
