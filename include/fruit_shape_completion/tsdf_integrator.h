#pragma once
// Integrates one view (a fruit point cloud in the map frame and the sensor origin; poses come
// from the robot, no ICP) into a TsdfMap.
//
// Strategy ("merged", as voxblox's merged integrator): points falling into the same voxel are
// averaged into one ray whose weight is their count, so a close-up view with ~16 points per
// voxel casts ~16x fewer rays with the same result. Each ray updates the voxels it crosses
// within the truncation band around its end point (from the sensor on with carve_free_space).
#include <fruit_shape_completion/statistical_outlier_filter.h>
#include <fruit_shape_completion/tsdf_map.h>

#include <Eigen/Geometry>
#include <string>

namespace fruit_shape_completion {

struct TsdfIntegratorParams {
  double truncation_voxels = 4.0;  // truncation distance in voxels
  enum class Weighting { kConstant, kInverseSquare };
  Weighting weighting = Weighting::kConstant;  // kInverseSquare: 1 / range^2 (range in m)
  bool drop_off = true;      // weight falls linearly behind the surface (-1 voxel .. -truncation)
  // Behind the surface a ray updates at most truncation * cos(incidence) (at least a quarter of
  // it), the incidence from the normal of its neighbouring end points. Grazing rays otherwise
  // run out of a curved fruit within the band and mark outside voxels as inside: on a 4 cm
  // sphere seen from all around that moves the surface 0.4 mm out, +4 % volume.
  bool incidence_limited_back_band = true;
  double max_weight = 10000.0;
  double min_range = 0.05;   // [m] points closer to the sensor are dropped
  double max_range = 3.0;    // [m] and farther
  bool carve_free_space = false;  // also update the free space from the sensor to the band
  bool remove_outliers = true;    // statistical outlier removal of the (voxel-merged) cloud
  OutlierFilterParams outliers;
  std::size_t max_points = 2000000;  // larger clouds are refused whole (6 VGA frames)
  void validate() const;  // throws std::invalid_argument
};

struct IntegrationReport {
  std::string error;  // non-empty: the whole view was refused, the map is unchanged
  std::string warning;  // something was dropped (counts below); the rest was integrated
  std::size_t points_in = 0;
  std::size_t non_finite = 0;
  std::size_t out_of_range = 0;  // closer than min_range, farther than max_range, or behind the sensor
  std::size_t outside_map = 0;   // rays partly outside the crop box or the map's key range
  std::size_t over_budget = 0;   // rays partly dropped: new blocks needed beyond the memory budget
  std::size_t outliers = 0;      // merged points removed by the outlier filter
  std::size_t rays = 0;
  std::size_t voxel_updates = 0;
  double seconds = 0.0;  // all of it; the phases:
  double merge_seconds = 0.0;          // checks and merging the points per voxel
  double neighbourhood_seconds = 0.0;  // outlier statistics and normals (0 when both are off)
  double ray_seconds = 0.0;            // ray casting and the update of the map
  bool ok() const { return error.empty(); }
};

class TsdfIntegrator {
 public:
  explicit TsdfIntegrator(const TsdfIntegratorParams& params = TsdfIntegratorParams());
  const TsdfIntegratorParams& params() const { return params_; }

  IntegrationReport integrate(TsdfMap& map, const PointList& points,
                              const Eigen::Vector3d& sensor_origin) const;
  // With the full sensor pose (sensor -> map, optical axis +z): points behind or beside the
  // image plane (z <= min_range in the sensor frame) are dropped as out of range.
  IntegrationReport integrate(TsdfMap& map, const PointList& points,
                              const Eigen::Isometry3d& sensor_pose) const;

 private:
  IntegrationReport integrateImpl(TsdfMap& map, const PointList& points,
                                  const Eigen::Vector3d& origin, const Eigen::Isometry3d* pose) const;

  TsdfIntegratorParams params_;
};

}  // namespace fruit_shape_completion
