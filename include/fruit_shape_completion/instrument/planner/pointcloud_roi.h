#pragma once
// pointcloud_roi's RedClusterFilter on one rendered frame, step for step as
// ../shared/upstream/README.md lists it: the whole coloured cloud in the map frame, PCL's
// VoxelGrid (1 cm, centroid and mean colour per leaf), the red test on the leaves' mean colours,
// PCL's StatisticalOutlierRemoval with its defaults (mean_k 1, stddev 0) over the red indices.
// What the upstream planner receives as a PointcloudWithRoi; an instrument, not the product.
#include <fruit_shape_completion/instrument/sim/fruit_mask.h>
#include <fruit_shape_completion/instrument/sim/rgbd_renderer.h>

#include <array>
#include <cstdint>
#include <vector>

namespace fruit_shape_completion {
namespace planner {

struct RoiCloud {
  PointList points;                               // map frame, one per occupied leaf
  std::vector<std::array<std::uint8_t, 3>> colours;  // the leaves' mean colours
  std::vector<std::int32_t> roi_indices;          // into points: the red leaves SOR kept
};

RoiCloud pointcloudRoi(const sim::RgbdFrame& frame, double leaf, const sim::RedThreshold& red_test);

}  // namespace planner
}  // namespace fruit_shape_completion
