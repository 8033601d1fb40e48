#include <fruit_shape_completion/ros/estimator_params.h>

#include <ros/param.h>

#include <algorithm>
#include <stdexcept>
#include <type_traits>

namespace fruit_shape_completion {
namespace ros_io {

namespace {

// Present but of the wrong type (a string for a number, 0.5 for an integer) is an error, not
// a silent fallback to the default.
template <typename T>
void readParam(const ros::NodeHandle& nh, const std::string& name, T& value, std::vector<std::string>* known) {
  known->push_back(name);
  if (!nh.hasParam(name)) return;
  T v;
  XmlRpc::XmlRpcValue raw;
  // roscpp rounds a double into an int parameter: 64.5 voxels would silently become 65.
  const bool rounded = std::is_same<T, int>::value && nh.getParam(name, raw) && raw.getType() != XmlRpc::XmlRpcValue::TypeInt;
  if (rounded || !nh.getParam(name, v))
    throw std::runtime_error("parameter '" + nh.resolveName(name) + "' has the wrong type (expected " +
                             (std::is_same<T, int>::value           ? "an integer"
                              : std::is_same<T, bool>::value        ? "true/false"
                              : std::is_same<T, std::string>::value ? "a string"
                                                                    : "a number") +
                             ")");
  value = v;
}

}  // namespace

void rejectUnknownKeys(const ros::NodeHandle& nh, const std::vector<std::string>& known) {
  std::vector<std::string> names;
  if (!ros::param::getParamNames(names)) return;
  const std::string prefix = nh.getNamespace() == "/" ? "/" : nh.getNamespace() + "/";
  for (const auto& full : names) {
    if (full.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string key = full.substr(prefix.size(), full.find('/', prefix.size()) - prefix.size());
    if (std::find(known.begin(), known.end(), key) != known.end()) continue;
    std::string valid;
    for (const auto& k : known) valid += (valid.empty() ? "" : ", ") + k;
    throw std::runtime_error("unknown parameter '" + prefix + key + "' (valid: " + valid + ")");
  }
}

const std::vector<std::string>& pluginInputKeys() {
  static const std::vector<std::string> keys = {"superellipsoids_topic", "fruit_cloud_topic",     "camera_cloud_topic",
                                                "camera_pair_tolerance", "camera_buffer_frames", "camera_buffer_mb",
                                                "camera_mask_topic"};
  return keys;
}

void readStringParam(const ros::NodeHandle& nh, const std::string& name, std::string* value) {
  std::vector<std::string> known;
  readParam(nh, name, *value, &known);
}

void readNumberParam(const ros::NodeHandle& nh, const std::string& name, double* value) {
  std::vector<std::string> known;
  readParam(nh, name, *value, &known);
}

void readIntParam(const ros::NodeHandle& nh, const std::string& name, int* value) {
  std::vector<std::string> known;
  readParam(nh, name, *value, &known);
}

host::SuperellipsoidEstimatorParams readEstimatorParams(const ros::NodeHandle& nh,
                                                           const std::vector<std::string>& other_keys) {
  host::SuperellipsoidEstimatorParams p;
  std::vector<std::string> known = other_keys;
  auto read = [&](const std::string& name, auto& value) { readParam(nh, name, value, &known); };
  read("red_min_hue", p.input.red_test.min_hue);
  read("red_max_hue", p.input.red_test.max_hue);
  read("red_min_saturation", p.input.red_test.min_saturation);
  read("red_min_intensity", p.input.red_test.min_intensity);
  read("drop_depth_edges", p.input.drop_depth_edges);
  read("depth_edge_absolute", p.input.depth_edges.absolute);
  read("depth_edge_relative", p.input.depth_edges.relative);
  read("input_remove_outliers", p.input.remove_outliers);
  read("input_outlier_k", p.input.outliers.k);
  read("input_outlier_std_mul", p.input.outliers.std_mul);
  read("input_outlier_radius", p.input.outliers.search_radius);
  read("drop_veil_points", p.input.drop_veil_points);
  read("veil_radius", p.input.veil_radius);
  read("veil_angle_deg", p.input.veil_angle_deg);
  read("voxel_size", p.map.voxel_size);
  read("voxels_per_side", p.map.voxels_per_side);
  read("memory_budget_mb", p.map.memory_budget_mb);
  read("truncation_voxels", p.integrator.truncation_voxels);
  read("max_weight", p.integrator.max_weight);
  read("min_range", p.integrator.min_range);
  read("max_range", p.integrator.max_range);
  read("remove_outliers", p.integrator.remove_outliers);
  read("outlier_k", p.integrator.outliers.k);
  read("outlier_std_mul", p.integrator.outliers.std_mul);
  read("outlier_radius", p.integrator.outliers.search_radius);
  read("cluster_tolerance", p.pipeline.clustering.tolerance);
  read("cluster_min_size", p.pipeline.clustering.min_size);
  read("cluster_max_size", p.pipeline.clustering.max_size);
  read("normal_radius", p.pipeline.normals.radius);
  read("normal_max_edge_offset", p.pipeline.normals.max_edge_offset);
  read("center_lambda", p.pipeline.center_lambda);
  read("center_rim_margin", p.pipeline.center_rim_margin);
  read("refit_tolerance", p.pipeline.refit_tolerance);
  read("fit_threads", p.pipeline.threads);
  read("alpha", p.pipeline.fit.alpha);
  read("gamma", p.pipeline.fit.gamma);
  read("min_axis", p.pipeline.fit.min_axis);
  read("max_axis", p.pipeline.fit.max_axis);
  read("min_e", p.pipeline.fit.min_e);
  read("max_e", p.pipeline.fit.max_e);
  read("max_iterations", p.pipeline.fit.max_iterations);
  read("max_fit_points", p.pipeline.fit.max_points);
  read("fit_function_tolerance", p.pipeline.fit.function_tolerance);
  read("fit_stall_tolerance", p.pipeline.fit.stall_tolerance);
  read("max_rms", p.pipeline.fit.max_rms);
  read("fit_noise_bias", p.pipeline.fit.noise_bias);
  read("fit_size_prior", p.pipeline.fit.size_prior);
  read("split_rms", p.pipeline.split_rms);
  read("one_fruit_max_rms", p.pipeline.one_fruit_max_rms);
  read("missing_surface_samples", p.pipeline.missing.samples);
  read("missing_surface_threshold", p.pipeline.missing.threshold);
  read("publish_targets", p.shape_targets);  // the older name of shape_targets
  read("shape_targets", p.shape_targets);
  read("target_settled_coverage", p.targets.settled_coverage);
  read("targets_per_fruit", p.targets.per_fruit);
  read("target_offset", p.targets.offset);
  read("target_view_side", p.targets.view_side);
  read("target_view_gain", p.targets.view_gain);
  read("target_view_fov_deg", p.targets.view_fov_deg);
  read("target_view_max_range", p.targets.view_max_range);
  read("target_view_clearance", p.targets.view_clearance);
  rejectUnknownKeys(nh, known);
  try {
    p.input.validate();
    p.map.validate();
    p.integrator.validate();
    p.pipeline.validate();
    p.targets.validate();
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("bad parameter in " + nh.getNamespace() + ": " + e.what());
  }
  return p;
}

}  // namespace ros_io
}  // namespace fruit_shape_completion
