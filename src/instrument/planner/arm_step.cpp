#include "arm_step.h"

#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {
namespace planner {

bool placeArmAtStart(const sim::Scene& scene, const sim::RobotArm& arm, const sim::ArmMotion& motion,
                     const Eigen::Vector3d& look, std::mt19937& rng, Eigen::Vector3d* pos, sim::ArmState* state) {
  sim::ArmState home;
  home.q << 0, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0;
  home.base = scene.robot.kind == sim::RobotMount::Kind::kPole
                  ? scene.robot.base
                  : Eigen::Vector3d(std::clamp(pos->x(), scene.robot.xy_min.x(), scene.robot.xy_max.x()),
                                    std::clamp(pos->y(), scene.robot.xy_min.y(), scene.robot.xy_max.y()), scene.robot.top);
  std::normal_distribution<double> g(0.0, 1.0);
  bool placed = false;
  for (int i = 0; i < 2000 && !placed; ++i) {
    const Eigen::Vector3d c = i == 0 ? *pos : *pos + (0.02 + 0.3 * i / 2000.0) * Eigen::Vector3d{g(rng), g(rng), g(rng)};
    if ((c - look).norm() < 0.05 || !scene.workspace.contains(c)) continue;
    placed = arm.reach(PinholeCamera::lookingAt(c, look), home, motion, arm.plants(), state) ==
             sim::RobotArm::Reach::kReached;
    if (placed) *pos = c;
  }
  return placed;
}

sim::DistanceField occupiedField(const RoiOcTree& tree, double resolution) {
  PointList occupied;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    if (!tree.isNodeOccupied(*it)) continue;
    const Eigen::Vector3d c(it.getX(), it.getY(), it.getZ());
    const double size = it.getSize();
    const int n = std::max(1, static_cast<int>(std::ceil(size / resolution)));
    for (int x = 0; x < n; ++x)
      for (int y = 0; y < n; ++y)
        for (int z = 0; z < n; ++z)
          occupied.push_back(c + size * (Eigen::Vector3d(x, y, z) + Eigen::Vector3d::Constant(0.5)) / n -
                             Eigen::Vector3d::Constant(0.5 * size));
  }
  return sim::DistanceField::ofPoints(occupied, resolution, 0.2);
}

}  // namespace planner
}  // namespace fruit_shape_completion
