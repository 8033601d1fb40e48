#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/roi_planner_shape_estimators.h>

#include <chrono>

#include <ros/console.h>
#include <tf2_eigen/tf2_eigen.h>

namespace fruit_shape_completion {
namespace ros_io {

RoiPlannerShapeEstimators::RoiPlannerShapeEstimators(ros::NodeHandle& planner_nh, const std::string& map_frame)
    : map_frame_(map_frame) {
  loader_.load(planner_nh, map_frame, /*report_view_drops=*/true);
}

bool toRoiView(const sensor_msgs::PointCloud2& cloud, const std::vector<std::int32_t>& roi_indices,
               const geometry_msgs::Transform& transform, const std::string& map_frame, RoiView* view,
               std::string* error, const geometry_msgs::Transform* cloud_to_map) {
  if (!fromRoiCloud(cloud, roi_indices, &view->all, &view->fruit, &view->bad_indices, error)) return false;
  view->sensor_pose = tf2::transformToEigen(transform);
  const Eigen::Isometry3d to_map = cloud_to_map ? tf2::transformToEigen(*cloud_to_map) : Eigen::Isometry3d::Identity();
  if (!view->sensor_pose.matrix().allFinite() || !to_map.matrix().allFinite()) {
    *error = "non-finite transform";
    return false;
  }
  if (cloud_to_map) {
    view->sensor_pose = to_map * view->sensor_pose;
    for (auto& p : view->all) p = to_map * p;
    for (auto& p : view->fruit) p = to_map * p;
  } else if (cloud.header.frame_id != map_frame) {
    for (auto& p : view->all) p = view->sensor_pose * p;
    for (auto& p : view->fruit) p = view->sensor_pose * p;
  }
  return true;
}

void RoiPlannerShapeEstimators::insertView(const sensor_msgs::PointCloud2& cloud,
                                           const std::vector<std::int32_t>& roi_indices,
                                           const geometry_msgs::Transform& transform, double time,
                                           const geometry_msgs::Transform* cloud_to_map,
                                           const std::uint64_t* resets_seen) {
  if (empty()) return;
  {
    std::lock_guard<std::mutex> lock(calls_mutex_);
    if (closing_) return;
    ++calls_;
  }
  struct Done {
    RoiPlannerShapeEstimators* self;
    ~Done() {
      std::lock_guard<std::mutex> lock(self->calls_mutex_);
      if (--self->calls_ == 0) self->calls_done_.notify_all();
    }
  } done{this};
  try {
    std::shared_lock<std::shared_timed_mutex> no_reset(reset_mutex_);
    if (resets_seen != nullptr && *resets_seen != resets_.load()) {
      const std::size_t n = ++loader_.plannerViewDrops().before_reset;
      ROS_INFO_THROTTLE(10.0, "shape estimators: a view the planner mapped before its reset is not mapped (%zu so far)", n);
      return;
    }
    RoiView view;
    std::string error;
    if (!toRoiView(cloud, roi_indices, transform, map_frame_, &view, &error, cloud_to_map)) {
      skipView(error);  // throttled: a broken publisher sends every view malformed
      return;
    }
    if (view.bad_indices > 0) {
      const std::size_t skipped = loader_.plannerViewDrops().indices += view.bad_indices;
      ROS_WARN_THROTTLE(10.0, "shape estimators: %zu ROI indices out of range or on NaN points skipped (%zu so far)",
                        view.bad_indices, skipped);
    }
    loader_.host().onView({view.fruit, view.all, view.sensor_pose, time, host::ViewSource::kRoiCloud});
  } catch (const std::exception& e) {  // std::bad_alloc among them: drop this view, keep the planner running
    const std::size_t skipped = ++loader_.plannerViewDrops().views;
    ROS_ERROR("shape estimators: view dropped (%zu so far): %s", skipped, e.what());
  }
}

void RoiPlannerShapeEstimators::skipView(const std::string& why) {
  const std::size_t skipped = ++loader_.plannerViewDrops().views;
  ROS_WARN_THROTTLE(10.0, "shape estimators: view skipped (%zu so far): %s", skipped, why.c_str());
}

RoiPlannerShapeEstimators::~RoiPlannerShapeEstimators() {
  std::unique_lock<std::mutex> lock(calls_mutex_);
  closing_ = true;
  // A running call uses the estimators destroyed after this: it is waited for however long it
  // takes (a view's integration is bounded work), never abandoned.
  for (int waited = 2; !calls_done_.wait_for(lock, std::chrono::seconds(2), [this] { return calls_ == 0; }); waited += 2) {
    if (waited < 30)
      ROS_WARN("shape estimators: unloading, waiting for %d view call(s) still running", calls_);
    else  // a call waiting on ROS time (a tf lookup) with the clock stopped: say so, keep waiting
      ROS_ERROR_THROTTLE(30.0, "shape estimators: unloading, %d view call(s) still running after %d s (is /clock stopped?)",
                         calls_, waited);
  }
}

std::vector<octomap::point3d> RoiPlannerShapeEstimators::extraTargets() const {
  std::vector<octomap::point3d> directions;
  return extraTargets(&directions);
}

std::vector<octomap::point3d> RoiPlannerShapeEstimators::extraTargets(std::vector<octomap::point3d>* directions) const {
  ShapeTargetRound round = targetRound();
  *directions = std::move(round.directions);
  return std::move(round.points);
}

ShapeTargetRound::ShapeTargetRound(std::shared_ptr<const ShapeTargets> targets) : targets_(std::move(targets)) {
  if (!targets_) return;
  points.reserve(targets_->points.size());
  directions.reserve(targets_->points.size());
  for (std::size_t i = 0; i < targets_->points.size(); ++i) {
    points.push_back(toOctomapPoint(targets_->points[i]));
    directions.push_back(toOctomapPoint(targets_->directions[i]));
  }
}

ShapeTargetRound RoiPlannerShapeEstimators::targetRound() const {
  try {
    return ShapeTargetRound(loader_.host().sharedViewTargets());
  } catch (const std::exception& e) {
    ROS_ERROR("shape estimators: no extra targets this time: %s", e.what());
    return ShapeTargetRound();
  }
}

void RoiPlannerShapeEstimators::reset() {
  std::unique_lock<std::shared_timed_mutex> no_views(reset_mutex_, std::defer_lock);
  if (!no_views.try_lock_for(std::chrono::seconds(2)))
    ROS_WARN("shape estimators: reset after 2 s waiting for a view being handed over (is /clock paused?); "
             "that view may reach the new fruit map");
  ++resets_;
  loader_.plannerViewDrops().views = 0;
  loader_.plannerViewDrops().indices = 0;
  loader_.plannerViewDrops().before_reset = 0;
  loader_.host().reset();
}

}  // namespace ros_io
}  // namespace fruit_shape_completion
