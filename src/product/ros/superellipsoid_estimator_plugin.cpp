// fruit_shape_completion/SuperellipsoidEstimator: the superellipsoid shape estimator as a
// pluginlib plugin; publishes its state under its namespace after each update that changed it, and offers
// clear_map, save_map, load_map and export_fruits there, and its live settings through
// dynamic_reconfigure (cfg/Superellipsoid.cfg). With camera_cloud_topic it keeps the camera's last
// organized clouds and feeds the fruit map from the frame each planner view was made from
// (full resolution, the whole fruit input stage) instead of the view's 1 cm cloud.
#include <fruit_shape_completion/FilePath.h>
#include <fruit_shape_completion/SuperellipsoidConfig.h>
#include <fruit_shape_completion/host/superellipsoid_estimator.h>
#include <fruit_shape_completion/host/update_worker.h>
#include <fruit_shape_completion/ros/camera_frames.h>
#include <fruit_shape_completion/ros/estimator_params.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/upstream_messages.h>
#include <fruit_shape_completion/shape_estimator_plugin.h>

#include <dynamic_reconfigure/server.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <std_srvs/Empty.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_listener.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <deque>
#include <cstdio>
#include <memory>
#include <mutex>
#include <utility>

namespace fruit_shape_completion {

class SuperellipsoidEstimatorPlugin : public ShapeEstimatorPlugin {
 public:
  ~SuperellipsoidEstimatorPlugin() override {
    // No callback may start a view or a fit once the estimator is on its way out.
    camera_.shutdown();
    masks_sub_.shutdown();
    fruit_cloud_.shutdown();
    clear_.shutdown();
    save_.shutdown();
    load_.shutdown();
    export_.shutdown();
    reconfigure_.reset();
    if (estimator_) estimator_->cancelUpdate();
    own_updates_.reset();
  }
  void initialize(const std::string& name, ros::NodeHandle& nh, const std::string& map_frame) override {
    name_ = name;
    map_frame_ = map_frame;
    estimator_ = std::make_unique<host::SuperellipsoidEstimator>(ros_io::readEstimatorParams(nh, ros_io::pluginInputKeys()));
    // The live server below would clamp a start value into cfg/Superellipsoid.cfg's range with
    // no more than an INFO line; such a value is refused here, as the other start checks refuse.
    {
      const SuperellipsoidConfig start = configOf(estimator_->liveParams());
      SuperellipsoidConfig clamped = start;
      clamped.__clamp__();
      const std::string outside = describeChanges(start, clamped);
      if (!outside.empty())
        throw std::runtime_error("live settings outside the ranges of cfg/Superellipsoid.cfg (given -> nearest allowed): " +
                                 outside);
    }
    std::string superellipsoids_topic = ros_io::kUpstreamSuperellipsoidsTopic, fruit_cloud_topic;
    std::string camera_topic = "/camera/depth/points", mask_topic;
    int buffer_frames = 16, buffer_mb = 160;
    ros_io::readStringParam(nh, "superellipsoids_topic", &superellipsoids_topic);
    ros_io::readStringParam(nh, "fruit_cloud_topic", &fruit_cloud_topic);
    ros_io::readStringParam(nh, "camera_cloud_topic", &camera_topic);
    ros_io::readStringParam(nh, "camera_mask_topic", &mask_topic);
    ros_io::readNumberParam(nh, "camera_pair_tolerance", &pair_tolerance_);
    ros_io::readIntParam(nh, "camera_buffer_frames", &buffer_frames);
    ros_io::readIntParam(nh, "camera_buffer_mb", &buffer_mb);
    if (!(pair_tolerance_ >= 0.0 && pair_tolerance_ <= 10.0))
      throw std::runtime_error("parameter '" + nh.resolveName("camera_pair_tolerance") + "' must be in [0, 10] s");
    if (buffer_frames < 1 || buffer_frames > 1000)
      throw std::runtime_error("parameter '" + nh.resolveName("camera_buffer_frames") + "' must be in [1, 1000]");
    if (buffer_mb < 1 || buffer_mb > 65536)
      throw std::runtime_error("parameter '" + nh.resolveName("camera_buffer_mb") + "' must be in [1, 65536] MiB");
    publisher_ = std::make_unique<ros_io::FruitPublisher>(nh, map_frame, superellipsoids_topic);
    // Fits the plugin starts itself (fruit clouds, a camera at rest, a loaded map) run here,
    // never in a subscriber's or a service's callback.
    own_updates_ = std::make_unique<host::UpdateWorker>([this] {
      if (!host_enabled_) return;  // disabled by the host: nothing of its own either
      try {
        update();
      } catch (const std::exception& e) {  // std::bad_alloc among them: keep the last results
        ROS_ERROR_THROTTLE(10.0, "%s: update failed, the last results kept: %s", name_.c_str(), e.what());
      }
    });
    clear_ = nh.advertiseService("clear_map", &SuperellipsoidEstimatorPlugin::clearMap, this);
    save_ = nh.advertiseService("save_map", &SuperellipsoidEstimatorPlugin::saveMap, this);
    load_ = nh.advertiseService("load_map", &SuperellipsoidEstimatorPlugin::loadMap, this);
    export_ = nh.advertiseService("export_fruits", &SuperellipsoidEstimatorPlugin::exportFruits, this);
    // The server reads the start values the YAML put in this namespace; its first call applies
    // them unchanged. A configuration that still says publish_targets (the older name) has no
    // shape_targets for the server to read: it gets the value read at start, not the cfg default.
    if (nh.hasParam("publish_targets") && !nh.hasParam("shape_targets"))
      nh.setParam("shape_targets", estimator_->liveParams().shape_targets);
    reconfigure_ = std::make_unique<dynamic_reconfigure::Server<SuperellipsoidConfig>>(reconfigure_mutex_, nh);
    reconfigure_->setCallback([this](SuperellipsoidConfig& config, uint32_t) { reconfigure(config); });
    if (!fruit_cloud_topic.empty() || !camera_topic.empty()) {
      tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
      tf_listener_ = std::make_unique<tf2_ros::TransformListener>(*tf_buffer_);
    }
    std::string fed_by = "the planner's views";
    if (!fruit_cloud_topic.empty()) {
      // An external detector's full-resolution fruit clouds: the planner's views (1 cm after
      // pointcloud_roi's downsampling) then no longer feed the 4 mm fruit map.
      fruit_cloud_ = nh.subscribe(fruit_cloud_topic, 2, &SuperellipsoidEstimatorPlugin::onFruitCloud, this);
      fed_by = "fruit clouds on " + nh.resolveName(fruit_cloud_topic);
    } else if (!camera_topic.empty()) {
      camera_buffer_ = std::make_unique<ros_io::CameraFrameBuffer>(static_cast<std::size_t>(buffer_frames),
                                                                   static_cast<std::size_t>(buffer_mb) << 20);
      camera_ = nh.subscribe(camera_topic, 4, &SuperellipsoidEstimatorPlugin::onCameraCloud, this);
      fed_by = "the camera frames on " + nh.resolveName(camera_topic) + " paired with the planner's views";
      if (!mask_topic.empty()) {
        max_masks_ = static_cast<std::size_t>(buffer_frames);
        masks_sub_ = nh.subscribe(mask_topic, 4, &SuperellipsoidEstimatorPlugin::onMask, this);
        fed_by += ", masked by " + nh.resolveName(mask_topic);
      }
    }
    ROS_INFO("shape estimator '%s' ready in %s: superellipsoids on %s, fruit map fed by %s", name.c_str(),
             nh.getNamespace().c_str(), nh.resolveName(superellipsoids_topic).c_str(), fed_by.c_str());
  }
  std::string name() const override { return name_; }
  void insertView(const host::ViewData& view) override {
    check();
    ++planner_views_;
    if (fruit_cloud_) return;  // the map is fed by the full-resolution topic
    last_planner_view_ = ros::WallTime::now().toSec();
    if (camera_buffer_) {
      std::lock_guard<std::mutex> lock(still_mutex_);
      rest_.plannerViewAt(view.sensor_pose);
    }
    if (camera_buffer_ && view.source != host::ViewSource::kCameraFrame) {
      std::string why;
      if (integrateCameraFrame(view.time, &why)) return;
      // The view's own cloud (pointcloud_roi's 1 cm voxels) is the fallback: less detail, but
      // the view is not lost.
      const std::size_t n = ++fallback_views_;
      ROS_WARN_THROTTLE(10.0, "%s: view at %.3f s: no camera frame used (%s); its %s cloud went into the map instead "
                        "(%zu views so far)", name_.c_str(), view.time, why.c_str(),
                        view.source == host::ViewSource::kRoiCloud ? "1 cm ROI" : "own", n);
    }
    integrate(view);
  }
  void update() override {
    check();
    estimator_->update();
    logIntegration();
    if (const int oversized = estimator_->lastPipelineStats().left_out.oversized; oversized > 0)
      ROS_WARN_THROTTLE(10.0, "%s: %d surface clusters hold more than cluster_max_size points and were not fitted "
                        "(fruits and leaves grown into one, or a cloud far denser than the map)", name_.c_str(), oversized);
    {
      // Read and publish in one step with reset(): a fit that a reset overtook stored nothing, so
      // it publishes nothing after the reset's cleared state, never its own.
      std::lock_guard<std::mutex> lock(publish_mutex_);
      last_update_ = ros::WallTime::now().toSec();
      // An update that stored no new results (no view since the last) publishes nothing: the
      // topics are latched, and a row's markers and surface run to megabytes per message.
      std::shared_ptr<const std::vector<FruitEstimate>> results = estimator_->sharedFruits();
      if (results == published_) return;
      published_ = std::move(results);
      publisher_->publish(estimator_->estimates(), estimator_->surfaceBlocks(), ros::Time::now());
    }
    // Outside the lock a reset takes: the markers and clouds (megabytes on a row) are built from
    // the latest state kept, which after a reset is the reset's.
    publisher_->sendVisuals();
  }
  void cancelUpdate() override {
    if (estimator_) estimator_->cancelUpdate();
  }
  void enabledChanged(bool enabled) noexcept override { host_enabled_ = enabled; }
  std::vector<FruitEstimate> fruits() const override { return check(), estimator_->fruits(); }
  PointList extraTargets() const override { return check(), estimator_->extraTargets(); }
  ShapeTargets viewTargets() const override { return check(), estimator_->viewTargets(); }
  std::shared_ptr<const std::vector<FruitEstimate>> sharedFruits() const override {
    return check(), estimator_->sharedFruits();
  }
  std::shared_ptr<const ShapeTargets> sharedViewTargets() const override {
    return check(), estimator_->sharedViewTargets();
  }
  void reset() override {
    check();
    if (camera_buffer_) camera_buffer_->clear();
    std::unique_lock<std::mutex> lock(publish_mutex_);
    estimator_->reset();
    publisher_->publish({}, SurfaceBlocks(), ros::Time::now());
    published_ = estimator_->sharedFruits();  // the cleared results, published just now
    // Counted since start or reset, as the estimator's counters (but "planner views received since
    // start", which says so).
    for (auto* counter : {&fruit_cloud_non_finite_, &fruit_clouds_skipped_, &fallback_views_, &no_frame_, &no_tf_,
                          &bad_frames_, &rest_no_tf_, &frames_received_, &not_organized_, &clock_jumps_, &too_large_,
                          &masks_received_, &masks_refused_, &frames_without_mask_, &rests_at_planner_pose_})
      *counter = 0;
    {
      std::lock_guard<std::mutex> still_lock(still_mutex_);
      rest_.reset();
    }
    lock.unlock();
    publisher_->sendVisuals();  // empty: cheap
  }
  std::vector<std::pair<std::string, std::string>> diagnostics() const override {
    check();
    const host::EstimatorStatus s = status();
    const double since = last_update_ > 0 ? ros::WallTime::now().toSec() - last_update_ : -1.0;
    const auto trust = medianTrust();
    return {{"planner views received since start", std::to_string(planner_views_)},
            {"views", std::to_string(s.input.views)},
            {"views refused", std::to_string(s.views_refused)},
            {"views without fruit points", std::to_string(s.views_without_fruit)},
            {"views overtaken by a reset (in insertView when it came; not mapped)", std::to_string(s.views_overtaken_by_reset)},
            {"views waiting for the map (integrated at the next update)", std::to_string(estimator_->pendingViews())},
            {"map blocks", std::to_string(s.blocks) + " of " + std::to_string(s.max_blocks)},
            {"map memory [MiB]", std::to_string(s.memory_mb)},
            {"points skipped (NaN/Inf, range)", std::to_string(s.points_skipped)},
            {"rays outside the map", std::to_string(s.rays_outside)},
            {"rays over the memory budget", std::to_string(s.rays_over_budget)},
            {"fruits", std::to_string(s.fruits)},
            {"surface clusters too large to fit (formed at the last update, around the blocks it changed; "
             "cluster_max_size)",
             std::to_string(s.oversized_clusters)},
            {"surface points in clusters too small to fit (formed at the last update, around the blocks it "
             "changed; cluster_min_size)",
             std::to_string(s.undersized_points)},
            {"fruit volumes: median 90 % interval half-width [%]", trust.first},
            {"fruit centres: median 90 % radius [mm]", trust.second},
            {"fruit clouds skipped (malformed, wrong frame, no transform, dropped)", std::to_string(fruit_clouds_skipped_)},
            {"camera frames received", std::to_string(frames_received_)},
            {"views fed by their camera frame", std::to_string(s.input.camera_frames)},
            {"views fed by their own (1 cm) cloud: no frame paired", std::to_string(fallback_views_)},
            {"  of which: no frame within the tolerance", std::to_string(no_frame_)},
            {"  of which: no tf for the frame", std::to_string(no_tf_)},
            {"  of which: malformed frame", std::to_string(bad_frames_)},
            {"camera rests not taken without a planner: its last view stood there", std::to_string(rests_at_planner_pose_)},
            {"camera frames without a planner and without a transform to the map (not mapped)", std::to_string(rest_no_tf_)},
            {"camera clouds not organized (ignored)", std::to_string(not_organized_)},
            {"camera clock jumps back (buffer cleared)", std::to_string(clock_jumps_)},
            {"camera frames too large for the buffer", std::to_string(too_large_)},
            {"camera masks received", std::to_string(masks_received_)},
            {"camera masks refused (not mono8, wrong size)", std::to_string(masks_refused_)},
            {"camera frames without their mask (red test used)", std::to_string(frames_without_mask_)},
            {"camera frames evicted unpaired", std::to_string(camera_buffer_ ? camera_buffer_->evicted() : 0)},
            {"input: fruit points masked", std::to_string(s.input.masked_points)},
            {"input: dropped at depth edges", std::to_string(s.input.depth_edge_points)},
            {"input: dropped as veil points (1 cm views)", std::to_string(s.input.veil_points)},
            {"input: dropped as outliers", std::to_string(s.input.outlier_points)},
            {"seconds since the last update", since < 0 ? "never" : std::to_string(since)}};
  }
  std::string diagnosticsWarning() const override {
    const host::EstimatorStatus s = status();
    const std::size_t counts[] = {s.views_refused,  s.rays_over_budget, fruit_clouds_skipped_, fallback_views_,
                                  not_organized_,   too_large_,         masks_refused_};
    const char* what[] = {"views refused", "rays over the memory budget", "fruit clouds skipped",
                          "views without their camera frame (their 1 cm cloud went in; camera_cloud_topic \"\" if meant)",
                          "camera clouds not organized", "camera frames too large", "camera masks refused"};
    constexpr std::size_t n = sizeof(counts) / sizeof(counts[0]);
    // WARN while input is being lost: one late frame must not leave the status WARN for the rest
    // of the run, only a loss that went on within the last minute.
    constexpr double kRecent = 60.0;  // [s]
    const double now = ros::WallTime::now().toSec();
    std::lock_guard<std::mutex> lock(loss_mutex_);
    loss_seen_.resize(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      if (counts[i] > loss_seen_[i]) last_loss_ = now;
      loss_seen_[i] = counts[i];  // a reset lowers them: nothing lost since
    }
    if (!(last_loss_ > 0.0 && now - last_loss_ < kRecent)) return {};
    std::string out;
    for (std::size_t i = 0; i < n; ++i)
      if (counts[i] > 0) out += (out.empty() ? "" : ", ") + std::to_string(counts[i]) + " " + what[i];
    return out + " since the last reset, more within the last minute (see the counters)";
  }

 private:
  void integrate(const host::ViewData& view) {
    const FruitInput in = estimator_->insertViewReporting(view);
    if (!in.ok()) ROS_WARN("%s: view skipped: %s", name_.c_str(), in.error.c_str());
  }
  // The views the last update integrated that the map refused or cut.
  void logIntegration() {
    for (const IntegrationReport& r : estimator_->takeIntegrationProblems()) {
      if (!r.ok()) ROS_WARN("%s: view skipped: %s", name_.c_str(), r.error.c_str());
      // Throttled: a camera that keeps seeing beyond the budget would otherwise log every view.
      // The totals are gathered only when the message is printed (the macro evaluates its
      // arguments then): they walk the map's blocks.
      if (!r.warning.empty())
        ROS_WARN_THROTTLE(10.0, "%s: %s (%s)", name_.c_str(), r.warning.c_str(), totals().c_str());
    }
  }
  void onFruitCloud(const sensor_msgs::PointCloud2ConstPtr& msg) {
    if (!host_enabled_) return;  // its status says disabled: it maps nothing until a reset
    try {
      PointList points;
      std::size_t non_finite = 0;
      std::string error;
      if (!ros_io::fromCloud(*msg, &points, &non_finite, &error)) {
        // Counted outside the macro: a throttled log evaluates its arguments only when it prints.
        const std::size_t skipped = ++fruit_clouds_skipped_;
        ROS_WARN_THROTTLE(10.0, "%s: fruit cloud skipped (%zu so far): %s", name_.c_str(), skipped, error.c_str());
        return;
      }
      if (non_finite > 0) {
        const std::size_t so_far = fruit_cloud_non_finite_ += non_finite;
        ROS_WARN_THROTTLE(10.0, "%s: %zu NaN/Inf points of a fruit cloud skipped (%zu so far)", name_.c_str(), non_finite,
                          so_far);
      }
      if (msg->header.frame_id.empty() || msg->header.frame_id == map_frame_) {
        const std::size_t skipped = ++fruit_clouds_skipped_;
        ROS_WARN_THROTTLE(10.0,
                          "%s: fruit cloud skipped (%zu so far): it must be in the camera frame (the sensor origin), "
                          "not '%s'",
                          name_.c_str(), skipped, msg->header.frame_id.c_str());
        return;
      }
      const Eigen::Isometry3d sensor_to_map = tf2::transformToEigen(
          tf_buffer_->lookupTransform(map_frame_, msg->header.frame_id, msg->header.stamp, ros::Duration(0.2)));
      for (auto& p : points) p = sensor_to_map * p;
      integrate({points, points, sensor_to_map, msg->header.stamp.toSec(), host::ViewSource::kFruitCloud});
      own_updates_->request();
    } catch (const tf2::TransformException& e) {
      const std::size_t skipped = ++fruit_clouds_skipped_;
      ROS_WARN_THROTTLE(10.0, "%s: fruit cloud skipped (%zu so far): no transform to %s (%s)", name_.c_str(), skipped,
                        map_frame_.c_str(), e.what());
    } catch (const std::exception& e) {  // std::bad_alloc among them: drop this cloud, keep running
      ROS_ERROR("%s: fruit cloud dropped (%zu so far): %s", name_.c_str(), ++fruit_clouds_skipped_, e.what());
    }
  }
  // The buffered frame nearest the view's stamp, with its pose from tf at the frame's stamp,
  // through the whole input stage into the map. False (and why) if there is none to use.
  bool integrateCameraFrame(double stamp, std::string* why) {
    if (!(stamp > 0.0)) {
      *why = "the view has no stamp to pair a frame with";
      ++no_frame_;
      return false;
    }
    sensor_msgs::PointCloud2ConstPtr msg;
    try {
      msg = camera_buffer_->take(ros::Time(stamp), pair_tolerance_,
                                 frames_received_ > 0 || camera_.getNumPublishers() > 0 ? kFrameWait : 0.0);
    } catch (const std::runtime_error& e) {  // a stamp beyond ros::Time's range: the view's own cloud goes in
      *why = std::string("the view's stamp cannot pair a frame: ") + e.what();
      ++no_frame_;
      return false;
    }
    if (!msg) {
      *why = frames_received_ == 0 ? "nothing received on the camera topic"
                                   : "no camera frame within " + std::to_string(pair_tolerance_) + " s of the view";
      ++no_frame_;
      return false;
    }
    return integrateFrame(msg, why);
  }
  bool integrateFrame(const sensor_msgs::PointCloud2ConstPtr& msg, std::string* why) {
    Eigen::Isometry3d pose;
    try {
      pose = tf2::transformToEigen(
          tf_buffer_->lookupTransform(map_frame_, msg->header.frame_id, msg->header.stamp, ros::Duration(0.05)));
    } catch (const tf2::TransformException& e) {
      *why = std::string("no tf for the frame: ") + e.what();
      ++no_tf_;
      return false;
    }
    OrganizedFrame frame;
    if (!ros_io::fromOrganizedCloud(*msg, &frame, why)) {
      ++bad_frames_;
      return false;
    }
    const PointList none;
    host::ViewData view{none, none, pose, msg->header.stamp.toSec(), host::ViewSource::kCameraFrame};
    view.camera_frame = &frame;
    std::vector<std::uint8_t> mask;
    if (masks_sub_ && maskFor(msg->header.stamp, frame.width, frame.height, &mask)) view.fruit_mask = &mask;
    integrate(view);
    return true;
  }
  void onMask(const sensor_msgs::ImageConstPtr& msg) {
    ++masks_received_;
    if (msg->encoding != "mono8" && msg->encoding != "8UC1") {
      const std::size_t refused = ++masks_refused_;
      ROS_WARN_THROTTLE(10.0, "%s: camera mask ignored (%zu so far): encoding '%s', not mono8", name_.c_str(), refused,
                        msg->encoding.c_str());
      return;
    }
    std::lock_guard<std::mutex> lock(masks_mutex_);
    masks_.push_back(msg);
    while (masks_.size() > max_masks_) masks_.pop_front();
  }
  // The mask with the frame's stamp as one byte per pixel; false (warned, counted) if there is
  // none or it does not fit the frame: the red test then decides.
  bool maskFor(const ros::Time& stamp, int width, int height, std::vector<std::uint8_t>* out) {
    sensor_msgs::ImageConstPtr mask;
    {
      std::lock_guard<std::mutex> lock(masks_mutex_);
      for (const auto& m : masks_)
        if (std::abs(m->header.stamp.toSec() - stamp.toSec()) < 1e-3) mask = m;  // ros::Time's difference throws past 68 years
    }
    if (!mask) {
      const std::size_t without = ++frames_without_mask_;
      ROS_WARN_THROTTLE(10.0, "%s: no camera mask with the frame's stamp: the red test decides (%zu frames so far)",
                        name_.c_str(), without);
      return false;
    }
    if (static_cast<int>(mask->width) != width || static_cast<int>(mask->height) != height ||
        mask->step < mask->width || mask->data.size() < std::size_t(mask->step) * mask->height) {
      const std::size_t refused = ++masks_refused_;
      ROS_WARN_THROTTLE(10.0, "%s: camera mask of %ux%u refused for a %dx%d frame (%zu so far): the red test decides",
                        name_.c_str(), mask->width, mask->height, width, height, refused);
      return false;
    }
    out->resize(static_cast<std::size_t>(width) * height);
    for (int v = 0; v < height; ++v)
      std::memcpy(out->data() + static_cast<std::size_t>(v) * width, mask->data.data() + std::size_t(v) * mask->step,
                  static_cast<std::size_t>(width));
    return true;
  }
  void onCameraCloud(const sensor_msgs::PointCloud2ConstPtr& msg) {
    try {
      ++frames_received_;
      if (msg->height <= 1) {
        const std::size_t ignored = ++not_organized_;
        ROS_WARN_THROTTLE(10.0, "%s: camera cloud ignored (%zu so far): not organized (height %u); camera_cloud_topic "
                          "must be the camera driver's cloud", name_.c_str(), ignored, msg->height);
        return;
      }
      switch (camera_buffer_->push(msg)) {
        case ros_io::CameraFrameBuffer::Push::kClockJumpedBack:
          ++clock_jumps_;
          ROS_WARN("%s: camera stamps went back in time (a bag looping?): buffered frames dropped, the map kept",
                   name_.c_str());
          break;
        case ros_io::CameraFrameBuffer::Push::kTooLarge: {
          const std::size_t ignored = ++too_large_;
          ROS_WARN_THROTTLE(10.0, "%s: camera cloud of %zu bytes exceeds camera_buffer_mb; ignored (%zu so far)",
                            name_.c_str(), msg->data.size(), ignored);
          return;
        }
        case ros_io::CameraFrameBuffer::Push::kStored:
          break;
      }
      // Without a planner (no view for a while), a frame is taken when the camera has come to
      // rest, as pointcloud_roi's roi_cloud: once per rest, never every frame.
      const double silence = planner_views_ > 0 ? kStandaloneAfterPlanner : kStandaloneAfter;
      if (ros::WallTime::now().toSec() - last_planner_view_ > silence) integrateIfStill(msg);
    } catch (const std::exception& e) {  // std::bad_alloc among them: drop this frame, keep running
      ROS_ERROR("%s: camera cloud dropped: %s", name_.c_str(), e.what());
    }
  }
  void integrateIfStill(const sensor_msgs::PointCloud2ConstPtr& msg) {
    if (!host_enabled_) return;  // its status says disabled: it maps nothing until a reset
    Eigen::Isometry3d pose;
    try {
      // Waits for a late transform only while transforms come: with none (a tf tree without the
      // camera) every frame would hold a spinner thread for the whole wait. After a failure one
      // frame a second still waits, so frames that merely come before their transform recover.
      const double now = ros::WallTime::now().toSec();
      const bool retry = now - rest_tf_retried_.load() >= 1.0;
      if (!rest_tf_ok_ && retry) rest_tf_retried_ = now;
      const ros::Duration wait(rest_tf_ok_ || retry ? 0.1 : 0.0);
      pose = tf2::transformToEigen(tf_buffer_->lookupTransform(map_frame_, msg->header.frame_id, msg->header.stamp, wait));
      rest_tf_ok_ = true;
    } catch (const tf2::TransformException& e) {
      rest_tf_ok_ = false;
      const std::size_t n = ++rest_no_tf_;
      ROS_WARN_THROTTLE(10.0, "%s: camera frame not mapped without a planner: no transform %s -> %s (%s; %zu frames so far)",
                        name_.c_str(), msg->header.frame_id.c_str(), map_frame_.c_str(), e.what(), n);
      return;
    }
    {
      std::lock_guard<std::mutex> lock(still_mutex_);
      switch (rest_.observe(pose, msg->header.stamp.toSec())) {
        case ros_io::CameraRest::Frame::kTake:
          break;
        case ros_io::CameraRest::Frame::kPlannersPose:
          ++rests_at_planner_pose_;
          return;
        default:
          return;
      }
    }
    sensor_msgs::PointCloud2ConstPtr frame = camera_buffer_->take(msg->header.stamp, 0.0);  // not again for a view
    if (!frame) frame = msg;
    std::string why;
    if (!integrateFrame(frame, &why)) {
      ROS_WARN_THROTTLE(10.0, "%s: still camera frame not used: %s", name_.c_str(), why.c_str());
      return;
    }
    own_updates_->request();
  }
  bool clearMap(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
    reset();
    ROS_INFO("%s: fruit map cleared", name_.c_str());
    return true;
  }
  bool saveMap(FilePath::Request& req, FilePath::Response& res) {
    std::string error, warning;
    res.success = estimator_->saveMap(req.file_path, &error, &warning);
    if (!warning.empty()) ROS_WARN("%s: %s", name_.c_str(), warning.c_str());
    res.message = res.success ? "saved " + req.file_path : error;
    return true;
  }
  bool exportFruits(FilePath::Request& req, FilePath::Response& res) {
    std::string error, warning;
    std::size_t written = 0;
    res.success = estimator_->exportFruits(req.file_path, &error, &warning, &written);
    if (!warning.empty()) ROS_WARN("%s: %s", name_.c_str(), warning.c_str());
    res.message = res.success ? "exported " + std::to_string(written) + " fruits to " + req.file_path : error;
    if (!res.success) ROS_ERROR("%s: export_fruits: %s", name_.c_str(), error.c_str());
    return true;
  }
  // dynamic_reconfigure: a bad combination is refused whole and the server put back to the
  // settings in force; every accepted change is logged.
  void reconfigure(SuperellipsoidConfig& config) {
    const host::EstimatorLiveParams before = estimator_->liveParams();
    host::EstimatorLiveParams p = before;
    pairLiveFields(config, p, [](const auto& from_config, auto& to_live) { to_live = from_config; });
    try {
      estimator_->setLiveParams(p);
    } catch (const std::invalid_argument& e) {
      ROS_ERROR("%s: reconfigure refused, settings unchanged: %s", name_.c_str(), e.what());
      config = configOf(before);
      return;
    }
    const std::string changed = describeChanges(configOf(before), config);
    if (changed.empty()) return;
    ROS_INFO("%s: reconfigured (from the next view or fit): %s", name_.c_str(), changed.c_str());
    // A planner standing still sends no view: the own worker's update hands the targets over
    // under the new settings now.
    if (host_enabled_) own_updates_->request();
  }
  static SuperellipsoidConfig configOf(host::EstimatorLiveParams p) {
    SuperellipsoidConfig c = SuperellipsoidConfig::__getDefault__();
    pairLiveFields(c, p, [](auto& to_config, const auto& from_live) { to_config = from_live; });
    return c;
  }
  // Calls assign(config field, live field) for every live setting: one list for both ways.
  template <typename Assign>
  static void pairLiveFields(SuperellipsoidConfig& c, host::EstimatorLiveParams& p, Assign&& assign) {
    assign(c.shape_targets, p.shape_targets);
    assign(c.target_settled_coverage, p.targets.settled_coverage);
    assign(c.targets_per_fruit, p.targets.per_fruit);
    assign(c.target_offset, p.targets.offset);
    assign(c.target_view_side, p.targets.view_side);
    assign(c.target_view_gain, p.targets.view_gain);
    assign(c.target_view_fov_deg, p.targets.view_fov_deg);
    assign(c.target_view_max_range, p.targets.view_max_range);
    assign(c.target_view_clearance, p.targets.view_clearance);
    assign(c.red_min_hue, p.input.red_test.min_hue);
    assign(c.red_max_hue, p.input.red_test.max_hue);
    assign(c.red_min_saturation, p.input.red_test.min_saturation);
    assign(c.red_min_intensity, p.input.red_test.min_intensity);
    assign(c.drop_depth_edges, p.input.drop_depth_edges);
    assign(c.depth_edge_absolute, p.input.depth_edges.absolute);
    assign(c.depth_edge_relative, p.input.depth_edges.relative);
    assign(c.drop_veil_points, p.input.drop_veil_points);
    assign(c.veil_radius, p.input.veil_radius);
    assign(c.veil_angle_deg, p.input.veil_angle_deg);
    assign(c.input_remove_outliers, p.input.remove_outliers);
    assign(c.input_outlier_k, p.input.outliers.k);
    assign(c.input_outlier_std_mul, p.input.outliers.std_mul);
    assign(c.input_outlier_radius, p.input.outliers.search_radius);
    assign(c.refit_tolerance, p.refit_tolerance);
    assign(c.max_fit_points, p.max_fit_points);
    assign(c.fit_function_tolerance, p.fit_function_tolerance);
    assign(c.fit_stall_tolerance, p.fit_stall_tolerance);
    assign(c.fit_noise_bias, p.fit_noise_bias);
    assign(c.fit_size_prior, p.fit_size_prior);
  }
  // "name old -> new" for each parameter that differs.
  static std::string describeChanges(const SuperellipsoidConfig& a, const SuperellipsoidConfig& b) {
    std::string out;
    for (const auto& param : SuperellipsoidConfig::__getParamDescriptions__()) {
      boost::any va, vb;
      param->getValue(a, va);
      param->getValue(b, vb);
      const std::string sa = anyToString(va), sb = anyToString(vb);
      if (sa != sb) out += (out.empty() ? "" : ", ") + param->name + " " + sa + " -> " + sb;
    }
    return out;
  }
  static std::string anyToString(const boost::any& v) {
    if (const bool* b = boost::any_cast<bool>(&v)) return *b ? "true" : "false";
    if (const int* i = boost::any_cast<int>(&v)) return std::to_string(*i);
    if (const double* d = boost::any_cast<double>(&v)) {
      char buf[32];
      std::snprintf(buf, sizeof(buf), "%g", *d);
      return buf;
    }
    if (const std::string* s = boost::any_cast<std::string>(&v)) return *s;
    return "?";
  }
  bool loadMap(FilePath::Request& req, FilePath::Response& res) {
    if (!host_enabled_) {  // nothing would be fitted, and the reset that enables it clears the map
      res.success = false;
      res.message = "estimator disabled (see /diagnostics); reset the planner's estimators, then load";
      return true;
    }
    std::string error, warning;
    res.success = estimator_->loadMap(req.file_path, &error, &warning);
    if (!warning.empty()) ROS_WARN("%s: %s", name_.c_str(), warning.c_str());
    if (res.success) {
      {
        std::lock_guard<std::mutex> lock(still_mutex_);
        rest_.reset();  // the loaded map has not seen where the camera rests
      }
      own_updates_->request();
    }
    res.message = res.success ? "loaded " + req.file_path : error;
    return true;
  }
  // The median of a value over the accepted fruits, as text ("-": none).
  static std::string medianText(std::vector<double> v) {
    if (v.empty()) return "-";
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    char text[32];
    std::snprintf(text, sizeof(text), "%.1f", v[v.size() / 2]);
    return text;
  }
  // The medians of the accepted fruits' 90 % volume interval half-widths [%] and 90 % centre
  // radii [mm].
  std::pair<std::string, std::string> medianTrust() const {
    std::vector<double> hw, r;
    for (const auto& f : *estimator_->sharedFruits()) {
      if (f.volume > 0.0) hw.push_back(50.0 * (f.volume_hi - f.volume_lo) / f.volume);
      r.push_back(1e3 * f.center_r90);
    }
    return {medianText(std::move(hw)), medianText(std::move(r))};
  }
  // The estimator's counters with what this plugin dropped before the estimator saw it.
  host::EstimatorStatus status() const {
    host::EstimatorStatus s = estimator_->status();
    s.points_skipped += fruit_cloud_non_finite_;  // detector clouds' NaN/Inf, dropped on reading
    return s;
  }
  std::string totals() const {
    const host::EstimatorStatus s = status();
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
  std::unique_ptr<host::SuperellipsoidEstimator> estimator_;
  std::unique_ptr<ros_io::FruitPublisher> publisher_;
  std::atomic<double> last_update_{0.0};  // wall time of the last update [s]
  std::mutex publish_mutex_;  // orders publishing after an update with a reset's
  // The results last published (held, so that no later result can reuse its address).
  std::shared_ptr<const std::vector<FruitEstimate>> published_;
  std::unique_ptr<host::UpdateWorker> own_updates_;
  ros::ServiceServer clear_, save_, load_, export_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<SuperellipsoidConfig>> reconfigure_;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  ros::Subscriber fruit_cloud_;
  // The camera input (camera_cloud_topic).
  static constexpr double kStandaloneAfter = 5.0;  // [s] without a planner view: frames taken at rest
  // ... once a planner has sent views: one that plans and moves for long between them (failed
  // attempts, insert_scan_if_not_moved false) is still there, and its next view will map the pose.
  static constexpr double kStandaloneAfterPlanner = 30.0;
  // [s] a view built from a frame (pointcloud_roi) may overtake the frame on another connection
  static constexpr double kFrameWait = 0.05;
  double pair_tolerance_ = 0.05;                   // [s] view stamp to frame stamp
  std::unique_ptr<ros_io::CameraFrameBuffer> camera_buffer_;
  ros::Subscriber camera_;
  std::atomic<double> last_planner_view_{0.0};  // wall time [s]
  std::atomic<std::size_t> planner_views_{0}, frames_received_{0}, fallback_views_{0}, no_frame_{0}, no_tf_{0}, bad_frames_{0},
      not_organized_{0}, clock_jumps_{0}, too_large_{0}, rest_no_tf_{0};
  std::atomic<bool> host_enabled_{true};  // the host's verdict: disabled, its own inputs stop too
  std::atomic<bool> rest_tf_ok_{true};  // the last lookup for a frame without a planner found its transform
  std::atomic<double> rest_tf_retried_{0.0};  // [s, wall] when a frame last waited after a failure
  // An external detector's masks (camera_mask_topic), matched to frames by stamp.
  ros::Subscriber masks_sub_;
  std::mutex masks_mutex_;
  std::deque<sensor_msgs::ImageConstPtr> masks_;  // oldest first, at most max_masks_
  std::size_t max_masks_ = 16;
  std::atomic<std::size_t> masks_received_{0}, masks_refused_{0}, frames_without_mask_{0};
  std::atomic<std::size_t> fruit_clouds_skipped_{0};  // detector fruit clouds that never reached the map
  mutable std::mutex loss_mutex_;  // diagnosticsWarning's memory of the loss counters
  mutable std::vector<std::size_t> loss_seen_;
  mutable double last_loss_ = 0.0;  // [s, wall] when one of them last grew
  std::atomic<std::size_t> fruit_cloud_non_finite_{0};  // NaN/Inf points of detector fruit clouds, dropped on reading
  std::mutex still_mutex_;  // guards rest_
  ros_io::CameraRest rest_;  // without a planner: when the camera has come to rest
  std::atomic<std::size_t> rests_at_planner_pose_{0};  // rests not taken: the planner's last view stood there
};

}  // namespace fruit_shape_completion

PLUGINLIB_EXPORT_CLASS(fruit_shape_completion::SuperellipsoidEstimatorPlugin, fruit_shape_completion::ShapeEstimatorPlugin)
