#pragma once
// How much a candidate view would see: unknown ROI-octree cells along a grid of its rays, near
// the targets (the ROI contours and the estimators' predicted surface) or anywhere.
#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>

#include <cstdint>
#include <unordered_set>

namespace fruit_shape_completion {
namespace planner {

using KeySet = std::unordered_set<std::uint64_t>;

// 4 cm cells around the targets: unknown space there is worth seeing.
KeySet interestCells(const RoiOcTree& tree, const PointList& targets);
// Unknown octree cells seen along a grid of camera rays (stopping at occupied cells); only
// those in `interest` count unless interest is null.
double viewGain(const RoiOcTree& tree, const PinholeCamera& cam, const PlannerParams& p, const KeySet* interest);

}  // namespace planner
}  // namespace fruit_shape_completion
