#pragma once
// The planner loop's camera step: render one view, then hand the estimators what the chosen
// input delivers on a robot (the organized frame, pointcloud_roi's 1 cm view, or a detector's
// fruit points); the product's fruit input stage in the estimator does the rest.
#include <fruit_shape_completion/fruit_input_stage.h>
#include <fruit_shape_completion/instrument/planner/pointcloud_roi.h>
#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>
#include <fruit_shape_completion/instrument/sim/fruit_mask.h>

#include <cstdint>
#include <vector>

namespace fruit_shape_completion {
namespace planner {

struct CameraView {
  PinholeCamera camera;
  sim::RgbdFrame frame;
  std::vector<std::uint8_t> mask;  // the profile's red test on every pixel
  OrganizedFrame organized;        // kCamera input
  PointList fruit_points, all_points;
  // pointcloud_roi's PointcloudWithRoi of this frame: what the upstream planner's tree takes in,
  // whatever the estimators are given.
  RoiCloud roi;
  ViewSource source = ViewSource::kCameraFrame;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  // What the estimators get; refers to this view's members. With `detector_mask` a camera
  // frame carries `mask` in place of the product's red test (an external detector's mask).
  ViewData viewData(double time, bool detector_mask) const;
};

// View number `view` (it seeds the depth noise) from `camera`.
CameraView captureView(const sim::RgbdRenderer& renderer, const PinholeCamera& camera, const PlannerParams& p,
                       const sim::RedThreshold& red_test, int view);
// The mask against the renderer's labels: red-fruit pixels missed, other pixels taken for fruit.
void countMask(const CameraView& v, const std::vector<char>& red_fruit_material, EpisodeResult* result);
// The planner's ROI octree takes the view's PointcloudWithRoi as registerPointcloudWithRoi does.
void insertIntoOctree(RoiOcTree* tree, const CameraView& v);

}  // namespace planner
}  // namespace fruit_shape_completion
