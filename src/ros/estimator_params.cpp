#include <fruit_shape_completion/ros/estimator_params.h>

#include <stdexcept>
#include <type_traits>

namespace fruit_shape_completion {
namespace ros_io {

namespace {

// Present but of the wrong type (a string for a number, 0.5 for an integer) is an error, not
// a silent fallback to the default.
template <typename T>
void read(const ros::NodeHandle& nh, const std::string& name, T& value) {
  if (!nh.hasParam(name)) return;
  T v;
  if (!nh.getParam(name, v))
    throw std::runtime_error("parameter '" + nh.resolveName(name) + "' has the wrong type (expected " +
                             (std::is_same<T, int>::value ? "an integer" : std::is_same<T, bool>::value ? "true/false" : "a number") + ")");
  value = v;
}

}  // namespace

planner::SuperellipsoidEstimatorParams readEstimatorParams(const ros::NodeHandle& nh) {
  planner::SuperellipsoidEstimatorParams p;
  read(nh, "voxel_size", p.map.voxel_size);
  read(nh, "voxels_per_side", p.map.voxels_per_side);
  read(nh, "memory_budget_mb", p.map.memory_budget_mb);
  read(nh, "truncation_voxels", p.integrator.truncation_voxels);
  read(nh, "max_weight", p.integrator.max_weight);
  read(nh, "min_range", p.integrator.min_range);
  read(nh, "max_range", p.integrator.max_range);
  read(nh, "remove_outliers", p.integrator.remove_outliers);
  read(nh, "outlier_k", p.integrator.outliers.k);
  read(nh, "outlier_std_mul", p.integrator.outliers.std_mul);
  read(nh, "outlier_radius", p.integrator.outliers.search_radius);
  read(nh, "cluster_tolerance", p.pipeline.clustering.tolerance);
  read(nh, "cluster_min_size", p.pipeline.clustering.min_size);
  read(nh, "cluster_max_size", p.pipeline.clustering.max_size);
  read(nh, "normal_radius", p.pipeline.normals.radius);
  read(nh, "center_lambda", p.pipeline.center_lambda);
  read(nh, "alpha", p.pipeline.fit.alpha);
  read(nh, "gamma", p.pipeline.fit.gamma);
  read(nh, "min_axis", p.pipeline.fit.min_axis);
  read(nh, "max_axis", p.pipeline.fit.max_axis);
  read(nh, "min_e", p.pipeline.fit.min_e);
  read(nh, "max_e", p.pipeline.fit.max_e);
  read(nh, "max_iterations", p.pipeline.fit.max_iterations);
  read(nh, "max_rms", p.pipeline.fit.max_rms);
  read(nh, "missing_surface_samples", p.pipeline.missing.samples);
  read(nh, "missing_surface_threshold", p.pipeline.missing.threshold);
  read(nh, "publish_targets", p.publish_targets);
  try {
    p.map.validate();
    p.integrator.validate();
    p.pipeline.validate();
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("bad parameter in " + nh.getNamespace() + ": " + e.what());
  }
  return p;
}

}  // namespace ros_io
}  // namespace fruit_shape_completion
