#pragma once
// The fruit input stage: what turns a camera's view into the fruit points the TSDF fruit map
// integrates. The estimator runs it on every view it is given, whatever fed it:
//  - an organized RGB-D frame (depth_image_proc's point_cloud_xyzrgb, or the simulator's
//    render of one): the red test (or an external detector's mask), removal of pixels at
//    depth discontinuities, statistical outlier removal;
//  - an external detector's fruit cloud (no colours, no image): outlier removal only;
//  - pointcloud_roi's 1 cm ROI cloud: veil points (voxels strung along the camera's rays,
//    the blurred outlines of fruits) are dropped, seen from the sensor origin.
#include <fruit_shape_completion/depth_edges.h>
#include <fruit_shape_completion/hsi_red_test.h>
#include <fruit_shape_completion/statistical_outlier_filter.h>
#include <fruit_shape_completion/types.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

namespace fruit_shape_completion {

// One organized RGB-D frame in the camera's optical frame (z forward, x right, y down), row
// major, as depth_image_proc publishes it: NaN coordinates where the sensor has no return.
struct OrganizedFrame {
  int width = 0, height = 0;
  std::vector<float> xyz;         // 3 per pixel
  std::vector<std::uint8_t> rgb;  // 3 per pixel
  std::size_t pixels() const { return static_cast<std::size_t>(width) * static_cast<std::size_t>(height); }
  std::string problem() const;  // empty if the sizes agree
};

struct FruitInputParams {
  HsiRedTest red_test;
  bool drop_depth_edges = true;
  DepthEdgeParams depth_edges;
  // Statistical outlier removal of the fruit points (organized frames and fruit clouds): k
  // nearest within search_radius, as PCL's StatisticalOutlierRemoval. Off by default: on the
  // paper's scenario 2 it cost 4-6 well-measured fruits (docs/benchmarks.md); the TSDF
  // integrator's own filter on voxel-merged points stays on.
  bool remove_outliers = false;
  OutlierFilterParams outliers{5, 1.0, 0.005};
  // 1 cm ROI clouds: a fruit point is a veil point if another point within veil_radius lies
  // within veil_angle_deg of its camera ray (behind or in front of it).
  bool drop_veil_points = true;
  double veil_radius = 0.025;    // [m]
  double veil_angle_deg = 15.0;
  double veil_min_gap = 0.004;   // [m] closer points are the same surface
  void validate() const;  // throws std::invalid_argument naming the value
};

struct FruitInput {
  std::string error;  // non-empty: the input was refused whole
  PointList fruit;    // map frame
  PointList full;     // map frame: every pixel with a return (organized frames, if asked for)
  std::vector<std::uint8_t> mask;  // organized frames: the red test's or the external mask, per pixel
  std::size_t points = 0;       // pixels with a return, or cloud points
  std::size_t non_finite = 0;   // cloud points with a NaN/Inf coordinate (organized frames: no return, not counted)
  std::size_t masked = 0;       // fruit pixels by the red test or the mask
  std::size_t depth_edges = 0;  // of those, dropped at depth discontinuities
  std::size_t veil = 0;         // veil points dropped
  std::size_t outliers = 0;     // dropped by the outlier filter
  bool ok() const { return error.empty(); }
};

class FruitInputStage {
 public:
  explicit FruitInputStage(const FruitInputParams& params = FruitInputParams());
  const FruitInputParams& params() const { return params_; }

  // An organized frame and its pose (camera -> map). `external_mask`, if given, replaces the red
  // test: one byte per pixel, non-zero for fruit (a detector's mono8 mask). `full_cloud`: also
  // return every point of the frame in the map frame.
  FruitInput processFrame(const OrganizedFrame& frame, const Eigen::Isometry3d& camera_to_map,
                          const std::vector<std::uint8_t>* external_mask = nullptr, bool full_cloud = false) const;
  // An external detector's fruit points (any frame; distances do not depend on it).
  FruitInput processFruitCloud(const PointList& fruit) const;
  // pointcloud_roi's view: the whole downsampled cloud, its ROI points and the sensor origin,
  // all in the map frame.
  FruitInput processRoiCloud(const PointList& all, const PointList& fruit, const Eigen::Vector3d& sensor_origin) const;

 private:
  // Drops the outliers of out->fruit (if enabled) and counts them.
  void removeOutliers(FruitInput* out) const;
  FruitInputParams params_;
  TabulatedRedTest red_;  // params_.red_test
};

}  // namespace fruit_shape_completion
