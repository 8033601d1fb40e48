#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/roi_planner_shape_estimators.h>

#include <ros/console.h>
#include <tf2_eigen/tf2_eigen.h>

namespace fruit_shape_completion {
namespace ros_io {

RoiPlannerShapeEstimators::RoiPlannerShapeEstimators(ros::NodeHandle& planner_nh, const std::string& map_frame)
    : map_frame_(map_frame) {
  loader_.load(planner_nh, map_frame);
}

void RoiPlannerShapeEstimators::insertView(const sensor_msgs::PointCloud2& cloud,
                                           const std::vector<std::int32_t>& roi_indices,
                                           const geometry_msgs::Transform& transform, double time) {
  if (empty()) return;
  try {
    PointList all, fruit;
    std::size_t bad_indices = 0;
    std::string error;
    if (!fromRoiCloud(cloud, roi_indices, &all, &fruit, &bad_indices, &error)) {
      ++views_skipped_;
      ROS_WARN("shape estimators: view skipped (%zu so far): %s", std::size_t(views_skipped_), error.c_str());
      return;
    }
    if (bad_indices > 0) {
      indices_skipped_ += bad_indices;
      ROS_WARN_THROTTLE(10.0, "shape estimators: %zu ROI indices out of range or on NaN points skipped (%zu so far)",
                        bad_indices, std::size_t(indices_skipped_));
    }
    const Eigen::Isometry3d pose = tf2::transformToEigen(transform);
    if (!pose.matrix().allFinite()) {
      ++views_skipped_;
      ROS_WARN("shape estimators: view skipped (%zu so far): non-finite transform", std::size_t(views_skipped_));
      return;
    }
    if (cloud.header.frame_id != map_frame_) {
      for (auto& p : all) p = pose * p;
      for (auto& p : fruit) p = pose * p;
    }
    loader_.host().onView({fruit, all, pose, time});
  } catch (const std::exception& e) {  // std::bad_alloc among them: drop this view, keep the planner running
    ++views_skipped_;
    ROS_ERROR("shape estimators: view dropped (%zu so far): %s", std::size_t(views_skipped_), e.what());
  }
}

std::vector<octomap::point3d> RoiPlannerShapeEstimators::extraTargets() const {
  std::vector<octomap::point3d> out;
  try {
    const PointList targets = loader_.host().extraTargets();
    out.reserve(targets.size());
    for (const auto& p : targets)
      out.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  } catch (const std::exception& e) {
    ROS_ERROR("shape estimators: no extra targets this time: %s", e.what());
    out.clear();
  }
  return out;
}

void RoiPlannerShapeEstimators::reset() {
  loader_.host().reset();
  views_skipped_ = 0;
  indices_skipped_ = 0;
}

}  // namespace ros_io
}  // namespace fruit_shape_completion
