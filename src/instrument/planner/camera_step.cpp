#include "camera_step.h"

#include <fruit_shape_completion/instrument/planner/pointcloud_roi.h>

#include <cmath>

namespace fruit_shape_completion {
namespace planner {

CameraView captureView(const sim::RgbdRenderer& renderer, const PinholeCamera& camera, const PlannerParams& p,
                       const sim::RedThreshold& red_test, int view) {
  CameraView v;
  v.camera = camera;
  sim::DepthNoise noise;
  noise.enabled = p.depth_noise;
  if (p.paper_depth_noise) noise.model = sim::DepthNoise::Model::kPaper;
  noise.seed = p.seed * 100003u + static_cast<unsigned>(view);
  v.frame = renderer.render(camera, noise, p.render_threads);
  v.mask = sim::redMask(v.frame.rgb, v.frame.width, v.frame.height, red_test);
  v.pose = sim::cameraPose(camera);
  v.roi = pointcloudRoi(v.frame, p.roi_leaf, red_test);
  switch (p.input) {
    case PlannerParams::Input::kCamera:
      v.organized = sim::organizedFrame(v.frame);
      v.source = ViewSource::kCameraFrame;
      break;
    case PlannerParams::Input::kRoi:
      for (const auto i : v.roi.roi_indices) v.fruit_points.push_back(v.roi.points[static_cast<std::size_t>(i)]);
      v.all_points = v.roi.points;
      v.source = ViewSource::kRoiCloud;
      break;
    case PlannerParams::Input::kFruitCloud:
      v.fruit_points = sim::cloudsFromFrame(v.frame, v.mask).fruit;
      v.source = ViewSource::kFruitCloud;
      break;
  }
  return v;
}

ViewData CameraView::viewData(double time, bool detector_mask) const {
  ViewData given{fruit_points, all_points, pose, time, source};
  if (source == ViewSource::kCameraFrame) {
    given.camera_frame = &organized;
    if (detector_mask) given.fruit_mask = &mask;
  }
  return given;
}

void countMask(const CameraView& v, const std::vector<char>& red_fruit_material, EpisodeResult* result) {
  for (std::size_t px = 0; px < v.mask.size(); ++px) {
    const int m = v.frame.material[px];
    if (m < 0) continue;
    if (red_fruit_material[static_cast<std::size_t>(m)]) {
      ++result->mask_positives;
      result->mask_false_negatives += !v.mask[px];
    } else {
      ++result->mask_negatives;
      result->mask_false_positives += v.mask[px];
    }
  }
}

void insertIntoOctree(RoiOcTree* tree, const CameraView& v) {
  tree->insertRoiCloud(v.roi.points, v.roi.roi_indices, v.camera.position);
}

}  // namespace planner
}  // namespace fruit_shape_completion
