// fruit_shape_completion/SuperellipsoidEstimator: the superellipsoid shape estimator as a
// pluginlib plugin; publishes its state under its namespace after every update.
#include <fruit_shape_completion/planner/superellipsoid_estimator.h>
#include <fruit_shape_completion/ros/estimator_params.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/shape_estimator_plugin.h>

#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>

#include <cstdio>
#include <memory>

namespace fruit_shape_completion {

class SuperellipsoidEstimatorPlugin : public ShapeEstimatorPlugin {
 public:
  void initialize(const std::string& name, ros::NodeHandle& nh, const std::string& map_frame) override {
    name_ = name;
    estimator_ = std::make_unique<planner::SuperellipsoidEstimator>(ros_io::readEstimatorParams(nh));
    publisher_ = std::make_unique<ros_io::FruitPublisher>(nh, map_frame);
    ROS_INFO("shape estimator '%s' ready, publishing in %s", name.c_str(), nh.getNamespace().c_str());
  }
  std::string name() const override { return name_; }
  void insertView(const planner::ViewData& view) override {
    check();
    estimator_->insertView(view);
    const IntegrationReport r = estimator_->lastIntegration();
    if (!r.ok()) ROS_WARN("%s: view skipped: %s", name_.c_str(), r.error.c_str());
    // Throttled: a camera that keeps seeing beyond the budget would otherwise log every view.
    // The totals are gathered only when the message is printed (the macro evaluates its
    // arguments then): they walk the map's blocks.
    if (!r.warning.empty())
      ROS_WARN_THROTTLE(10.0, "%s: %s (%s)", name_.c_str(), r.warning.c_str(), totals().c_str());
  }
  void update() override {
    check();
    estimator_->update();
    publisher_->publish(estimator_->estimates(), estimator_->surface(), ros::Time::now());
  }
  std::vector<FruitEstimate> fruits() const override { return check(), estimator_->fruits(); }
  PointList extraTargets() const override { return check(), estimator_->extraTargets(); }
  void reset() override {
    check();
    estimator_->reset();
  }

 private:
  std::string totals() const {
    const planner::EstimatorStatus s = estimator_->status();
    char text[256];
    std::snprintf(text, sizeof(text),
                  "since start: %zu points skipped, %zu rays outside the map, %zu rays over the memory budget; "
                  "%zu of %zu blocks, %.0f MiB", s.points_skipped, s.rays_outside, s.rays_over_budget, s.blocks,
                  s.max_blocks, s.memory_mb);
    return text;
  }
  void check() const {
    if (!estimator_) throw std::runtime_error("shape estimator used before initialize()");
  }
  std::string name_ = "superellipsoid";
  std::unique_ptr<planner::SuperellipsoidEstimator> estimator_;
  std::unique_ptr<ros_io::FruitPublisher> publisher_;
};

}  // namespace fruit_shape_completion

PLUGINLIB_EXPORT_CLASS(fruit_shape_completion::SuperellipsoidEstimatorPlugin, fruit_shape_completion::ShapeEstimatorPlugin)
