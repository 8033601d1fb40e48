#include <fruit_shape_completion/ros/shape_estimator_loader.h>

#include <ros/ros.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <stdexcept>

namespace fruit_shape_completion {
namespace ros_io {

ShapeEstimatorLoader::ShapeEstimatorLoader()
    : loader_("fruit_shape_completion", "fruit_shape_completion::ShapeEstimatorPlugin"),
      host_([](const std::string& msg) { ROS_ERROR("%s", msg.c_str()); },
            host::ShapeEstimatorHost::Updates::kBackground) {}

void ShapeEstimatorLoader::load(ros::NodeHandle& nh, const std::string& map_frame, bool report_view_drops) {
  XmlRpc::XmlRpcValue list;
  if (!nh.getParam("shape_estimators", list)) {
    ROS_INFO("no 'shape_estimators' parameter in %s: running without shape estimators", nh.getNamespace().c_str());
    return;
  }
  if (list.getType() != XmlRpc::XmlRpcValue::TypeArray)
    throw std::runtime_error(nh.resolveName("shape_estimators") + " must be a list of {name, type}");
  for (int i = 0; i < list.size(); ++i) {
    XmlRpc::XmlRpcValue& e = list[i];
    if (e.getType() != XmlRpc::XmlRpcValue::TypeStruct || !e.hasMember("name") || !e.hasMember("type") ||
        e["name"].getType() != XmlRpc::XmlRpcValue::TypeString || e["type"].getType() != XmlRpc::XmlRpcValue::TypeString)
      throw std::runtime_error(nh.resolveName("shape_estimators") + "[" + std::to_string(i) +
                               "] must be {name: NAME, type: PACKAGE/CLASS}");
    const std::string name = e["name"], type = e["type"];
    // Each estimator owns the namespace of its name: two of one name would share parameters,
    // topics and services (the second's services fail to advertise).
    if (name.empty()) throw std::runtime_error(nh.resolveName("shape_estimators") + "[" + std::to_string(i) + "] has an empty name");
    for (int j = 0; j < i; ++j)
      if (static_cast<std::string>(list[j]["name"]) == name)
        throw std::runtime_error(nh.resolveName("shape_estimators") + "[" + std::to_string(i) + "] repeats the name '" +
                                 name + "' of entry " + std::to_string(j) + ": each estimator needs a namespace of its own");
    std::unique_ptr<ShapeEstimatorPlugin> plugin;
    try {
      plugin.reset(loader_.createUnmanagedInstance(type));
    } catch (const pluginlib::PluginlibException& ex) {
      std::string known;
      for (const auto& c : loader_.getDeclaredClasses()) known += " " + c;
      throw std::runtime_error("cannot load shape estimator '" + name + "' of type '" + type + "': " + ex.what() +
                               " (known types:" + known + ")");
    }
    ros::NodeHandle plugin_nh(nh, name);
    plugin->initialize(name, plugin_nh, map_frame);
    plugins_.push_back(plugin.get());
    names_.push_back(name);
    host_.add(std::move(plugin));
  }
  if (plugins_.empty()) return;
  diagnostics_ = std::make_unique<diagnostic_updater::Updater>(nh, nh);
  diagnostics_->setHardwareID("shape_estimators");
  for (std::size_t i = 0; i < plugins_.size(); ++i)
    diagnostics_->add("shape estimator " + plugins_[i]->name(),
                      [this, i](diagnostic_updater::DiagnosticStatusWrapper& s) { diagnose(i, s); });
  if (report_view_drops)
    diagnostics_->add("shape estimators: PointcloudWithRoi input", [this](diagnostic_updater::DiagnosticStatusWrapper& s) {
      const std::size_t views = planner_drops_.views, indices = planner_drops_.indices;
      s.add("views skipped (malformed, no transform, or dropped)", views);
      s.add("ROI indices skipped (out of range, non-finite points)", indices);
      // Expected around a reset, not a loss: the host's map was cleared after it took them.
      s.add("views from before the last reset (not mapped)", std::size_t(planner_drops_.before_reset));
      if (views + indices > 0) s.summary(diagnostic_msgs::DiagnosticStatus::WARN, "input skipped (see the log)");
      else s.summary(diagnostic_msgs::DiagnosticStatus::OK, "all input taken");
    });
  // force_update: update() has a period gate of its own, which a timer tick a little early skips.
  diagnostics_timer_ = nh.createTimer(ros::Duration(1.0), [this](const ros::TimerEvent&) { diagnostics_->force_update(); });
}

void ShapeEstimatorLoader::diagnose(std::size_t i, diagnostic_updater::DiagnosticStatusWrapper& status) const {
  if (!host_.enabled(i)) {
    status.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "disabled: " + host_.lastError(i));
    return;
  }
  try {
    for (const auto& kv : plugins_[i]->diagnostics()) status.add(kv.first, kv.second);
    const std::size_t oom = host_.outOfMemoryDrops(i);
    status.add("views dropped out of memory", oom);
    const host::ShapeEstimatorHost::UpdateStatus fit = host_.updateStatus(i);
    // The worker's runs, one per view the planner inserted (coalesced while one runs): a run with
    // nothing new to fit (a view without fruit) returns at once; the plugin's own updates (fruit
    // clouds, the camera at rest, load_map) are not among them.
    status.add("updates run for the planner's views (fits, or nothing new to fit)", fit.runs);
    status.add("view updates coalesced into a later update", fit.coalesced);
    status.add("last update duration [ms]", 1e3 * fit.last_seconds);
    status.add("seconds since the last update finished",
               fit.age_seconds < 0 ? std::string("never") : std::to_string(fit.age_seconds));
    status.add("update running", fit.running ? "yes" : "no");
    status.add("insertView latency, last 256 views: median [ms]", host_.insertLatencyMs(0.5));
    status.add("insertView latency, last 256 views: p95 [ms]", host_.insertLatencyMs(0.95));
    status.add("insertView latency, last 256 views: max [ms]", host_.insertLatencyMs(1.0));
    const std::string losing = plugins_[i]->diagnosticsWarning();
    if (oom > 0) status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "running; " + host_.lastError(i));
    else if (!losing.empty()) status.summary(diagnostic_msgs::DiagnosticStatus::WARN, "running; " + losing);
    else status.summary(diagnostic_msgs::DiagnosticStatus::OK, "running");
  } catch (const std::exception& e) {
    status.summary(diagnostic_msgs::DiagnosticStatus::WARN, std::string("no diagnostics: ") + e.what());
  }
}

}  // namespace ros_io
}  // namespace fruit_shape_completion
