// fruit_shape_completion/SuperellipsoidEstimator: the superellipsoid shape estimator as a
// pluginlib plugin; publishes its state under its namespace after every update and offers
// clear_map, save_map and load_map there.
#include <fruit_shape_completion/FilePath.h>
#include <fruit_shape_completion/planner/superellipsoid_estimator.h>
#include <fruit_shape_completion/ros/estimator_params.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/upstream_messages.h>
#include <fruit_shape_completion/shape_estimator_plugin.h>

#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <std_srvs/Empty.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_listener.h>

#include <atomic>
#include <cstdio>
#include <memory>

namespace fruit_shape_completion {

class SuperellipsoidEstimatorPlugin : public ShapeEstimatorPlugin {
 public:
  void initialize(const std::string& name, ros::NodeHandle& nh, const std::string& map_frame) override {
    name_ = name;
    map_frame_ = map_frame;
    estimator_ = std::make_unique<planner::SuperellipsoidEstimator>(
        ros_io::readEstimatorParams(nh, {"superellipsoids_topic", "fruit_cloud_topic"}));
    std::string superellipsoids_topic = ros_io::kUpstreamSuperellipsoidsTopic, fruit_cloud_topic;
    ros_io::readStringParam(nh, "superellipsoids_topic", &superellipsoids_topic);
    ros_io::readStringParam(nh, "fruit_cloud_topic", &fruit_cloud_topic);
    publisher_ = std::make_unique<ros_io::FruitPublisher>(nh, map_frame, superellipsoids_topic);
    clear_ = nh.advertiseService("clear_map", &SuperellipsoidEstimatorPlugin::clearMap, this);
    save_ = nh.advertiseService("save_map", &SuperellipsoidEstimatorPlugin::saveMap, this);
    load_ = nh.advertiseService("load_map", &SuperellipsoidEstimatorPlugin::loadMap, this);
    if (!fruit_cloud_topic.empty()) {
      // Full-resolution fruit clouds: the planner's views (1 cm after pointcloud_roi's
      // downsampling) then no longer feed the 4 mm fruit map.
      tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
      tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);
      fruit_cloud_ = nh.subscribe(fruit_cloud_topic, 2, &SuperellipsoidEstimatorPlugin::onFruitCloud, this);
    }
    ROS_INFO("shape estimator '%s' ready in %s: superellipsoids on %s, fruit map fed by %s", name.c_str(),
             nh.getNamespace().c_str(), nh.resolveName(superellipsoids_topic).c_str(),
             fruit_cloud_topic.empty() ? "the planner's views" : nh.resolveName(fruit_cloud_topic).c_str());
  }
  std::string name() const override { return name_; }
  void insertView(const planner::ViewData& view) override {
    check();
    if (fruit_cloud_) return;  // the map is fed by the full-resolution topic
    integrate(view);
  }
  void update() override {
    check();
    estimator_->update();
    last_update_ = ros::WallTime::now().toSec();
    publisher_->publish(estimator_->estimates(), estimator_->surface(), ros::Time::now());
  }
  std::vector<FruitEstimate> fruits() const override { return check(), estimator_->fruits(); }
  PointList extraTargets() const override { return check(), estimator_->extraTargets(); }
  void reset() override {
    check();
    estimator_->reset();
    publisher_->publish({}, {}, ros::Time::now());
  }
  std::vector<std::pair<std::string, std::string>> diagnostics() const override {
    check();
    const planner::EstimatorStatus s = estimator_->status();
    const double since = last_update_ > 0 ? ros::WallTime::now().toSec() - last_update_ : -1.0;
    return {{"views", std::to_string(s.views)},
            {"views refused", std::to_string(s.views_refused)},
            {"map blocks", std::to_string(s.blocks) + " of " + std::to_string(s.max_blocks)},
            {"map memory [MiB]", std::to_string(s.memory_mb)},
            {"points skipped (NaN/Inf, range)", std::to_string(s.points_skipped)},
            {"rays outside the map", std::to_string(s.rays_outside)},
            {"rays over the memory budget", std::to_string(s.rays_over_budget)},
            {"fruits", std::to_string(s.fruits)},
            {"seconds since the last update", since < 0 ? "never" : std::to_string(since)}};
  }

 private:
  void integrate(const planner::ViewData& view) {
    estimator_->insertView(view);
    const IntegrationReport r = estimator_->lastIntegration();
    if (!r.ok()) ROS_WARN("%s: view skipped: %s", name_.c_str(), r.error.c_str());
    // Throttled: a camera that keeps seeing beyond the budget would otherwise log every view.
    // The totals are gathered only when the message is printed (the macro evaluates its
    // arguments then): they walk the map's blocks.
    if (!r.warning.empty())
      ROS_WARN_THROTTLE(10.0, "%s: %s (%s)", name_.c_str(), r.warning.c_str(), totals().c_str());
  }
  void onFruitCloud(const sensor_msgs::PointCloud2ConstPtr& msg) {
    try {
      PointList points;
      std::size_t non_finite = 0;
      std::string error;
      if (!ros_io::fromCloud(*msg, &points, &non_finite, &error)) {
        ROS_WARN_THROTTLE(10.0, "%s: fruit cloud skipped: %s", name_.c_str(), error.c_str());
        return;
      }
      if (msg->header.frame_id.empty() || msg->header.frame_id == map_frame_) {
        ROS_WARN_THROTTLE(10.0, "%s: fruit cloud skipped: it must be in the camera frame (the sensor origin), not '%s'",
                          name_.c_str(), msg->header.frame_id.c_str());
        return;
      }
      const Eigen::Isometry3d sensor_to_map = tf2::transformToEigen(
          tf_buffer_->lookupTransform(map_frame_, msg->header.frame_id, msg->header.stamp, ros::Duration(0.2)));
      for (auto& p : points) p = sensor_to_map * p;
      integrate({points, points, sensor_to_map, msg->header.stamp.toSec()});
      update();
    } catch (const tf2::TransformException& e) {
      ROS_WARN_THROTTLE(10.0, "%s: fruit cloud skipped: no transform to %s (%s)", name_.c_str(), map_frame_.c_str(), e.what());
    } catch (const std::exception& e) {  // std::bad_alloc among them: drop this cloud, keep running
      ROS_ERROR("%s: fruit cloud dropped: %s", name_.c_str(), e.what());
    }
  }
  bool clearMap(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
    reset();
    ROS_INFO("%s: fruit map cleared", name_.c_str());
    return true;
  }
  bool saveMap(FilePath::Request& req, FilePath::Response& res) {
    std::string error;
    res.success = estimator_->saveMap(req.file_path, &error);
    res.message = res.success ? "saved " + req.file_path : error;
    return true;
  }
  bool loadMap(FilePath::Request& req, FilePath::Response& res) {
    std::string error;
    res.success = estimator_->loadMap(req.file_path, &error);
    if (res.success) update();
    res.message = res.success ? "loaded " + req.file_path : error;
    return true;
  }
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
  std::string name_ = "superellipsoid", map_frame_;
  std::unique_ptr<planner::SuperellipsoidEstimator> estimator_;
  std::unique_ptr<ros_io::FruitPublisher> publisher_;
  std::atomic<double> last_update_{0.0};  // wall time of the last update [s]
  ros::ServiceServer clear_, save_, load_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::Subscriber fruit_cloud_;
};

}  // namespace fruit_shape_completion

PLUGINLIB_EXPORT_CLASS(fruit_shape_completion::SuperellipsoidEstimatorPlugin, fruit_shape_completion::ShapeEstimatorPlugin)
