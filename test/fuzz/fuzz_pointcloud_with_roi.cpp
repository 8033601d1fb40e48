// libFuzzer target: a PointcloudWithRoi as the patched planner hands it over (cloud, ROI indices
// that may be negative, repeated or out of range, a transform that may be non-finite) read by
// ros_io::toRoiView, then inserted into the superellipsoid estimator and fitted. A bad message
// is refused with a message; a good one (points may still overflow to infinity under a huge
// transform: the map skips and counts them) never gives a non-finite fruit.
#include "fuzz_cloud_message.h"

#include <fruit_shape_completion/host/superellipsoid_estimator.h>
#include <fruit_shape_completion/ros/roi_planner_shape_estimators.h>

#include <cstdlib>

using namespace fruit_shape_completion;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzz::Bytes in(data, size);
  geometry_msgs::Transform transform;
  transform.translation.x = in.take<double>();
  transform.translation.y = in.take<double>();
  transform.translation.z = in.take<double>();
  transform.rotation.x = in.take<float>();  // floats: more inputs land near a unit quaternion
  transform.rotation.y = in.take<float>();
  transform.rotation.z = in.take<float>();
  transform.rotation.w = in.take<float>();
  std::vector<std::int32_t> indices(in.take<std::uint8_t>());
  for (auto& i : indices) i = in.take<std::int16_t>();
  const sensor_msgs::PointCloud2 cloud = fuzz::takeCloud(in);
  ros_io::RoiView view;
  std::string error;
  if (!ros_io::toRoiView(cloud, indices, transform, "world", &view, &error)) {
    if (error.empty()) std::abort();
    return 0;
  }
  if (view.fruit.size() + view.bad_indices != indices.size()) std::abort();  // every index accounted for
  if (!view.sensor_pose.matrix().allFinite()) std::abort();  // a non-finite transform is refused
  static host::SuperellipsoidEstimator estimator;  // one map over all inputs, as in a planner
  estimator.insertView({view.fruit, view.all, view.sensor_pose, 1.0, host::ViewSource::kRoiCloud});
  estimator.update();
  for (const auto& f : estimator.fruits())
    if (!f.center().allFinite() || !std::isfinite(f.volume)) std::abort();
  return 0;
}
