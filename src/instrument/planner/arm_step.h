#pragma once
// The planner loop's arm: where it starts, and the map it plans its moves in (the MoveIt
// stand-in: occupied octree cells as a distance field).
#include <fruit_shape_completion/instrument/planner/roi_octree.h>
#include <fruit_shape_completion/instrument/sim/robot_arm.h>

#include <random>

namespace fruit_shape_completion {
namespace planner {

// From a home posture near the start view, the start view itself or, if the arm cannot take
// it, the nearest reachable view looking at `look`. Updates *pos and *state; false if none.
bool placeArmAtStart(const sim::Scene& scene, const sim::RobotArm& arm, const sim::ArmMotion& motion,
                     const Eigen::Vector3d& look, std::mt19937& rng, Eigen::Vector3d* pos, sim::ArmState* state);

// What the planner's map has seen occupied, as a distance field at `resolution` (a merged leaf of
// 8^k equal cells becomes a grid over its cube).
sim::DistanceField occupiedField(const RoiOcTree& tree, double resolution);

}  // namespace planner
}  // namespace fruit_shape_completion
