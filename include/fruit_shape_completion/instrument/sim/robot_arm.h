#pragma once
// The camera's arm as in the paper's simulation: a UR5e on its mount (scene.robot), a camera
// 2 cm beyond the flange looking along the tool axis. Decides whether a camera pose can be
// reached (inverse kinematics within the joint limits, no link capsule inside the obstacles,
// the pole or the arm's own shoulder) and how long the arm takes to get there. The obstacles
// are the planner's choice: what its map has seen (as MoveIt plans), or the scene's plants
// (what the world allows, for checking a motion when it is executed).
#include <fruit_shape_completion/instrument/sim/analytic_depth_camera.h>
#include <fruit_shape_completion/instrument/sim/distance_field.h>
#include <fruit_shape_completion/instrument/sim/scene.h>
#include <fruit_shape_completion/instrument/sim/ur5e_kinematics.h>

#include <vector>

namespace fruit_shape_completion {
namespace sim {

struct ArmState {
  Eigen::Vector3d base = Eigen::Vector3d::Zero();  // world position of the arm's base
  JointVector q = JointVector::Zero();
};

// Time-optimal point-to-point motion per axis (trapezoidal velocity), all axes arriving
// together: what a joint-space trajectory executed at these scaled limits takes.
struct ArmMotion {
  // The planner scales the arm's rated speed as MoveIt's max_velocity_scaling_factor does.
  double velocity_scaling = 0.5, acceleration_scaling = 0.5;
  double joint_velocity = ur5e::kMaxVelocity;  // [rad/s] before scaling
  double joint_acceleration = 3.14;            // [rad/s^2] before scaling
  double gantry_velocity = 0.5, gantry_acceleration = 0.5;  // [m/s], [m/s^2] before scaling
  std::string problem() const;  // empty if usable
};

class RobotArm {
 public:
  static constexpr double kCameraOffset = 0.02;  // [m] lens beyond the flange

  // Builds the distance field of the scene's plants (collision_resolution cells). Throws
  // std::invalid_argument for a scene without an arm (robot.kind == kNone).
  explicit RobotArm(const Scene& scene, double collision_resolution = 0.01);

  enum class Reach { kReached, kNoInverse, kJointLimits, kCollision };
  // The state free of `obstacles` with the camera at `camera` (position and orientation) that
  // is quickest to reach from `from`; on the gantry the base may move too.
  Reach reach(const PinholeCamera& camera, const ArmState& from, const ArmMotion& motion,
              const DistanceField& obstacles, ArmState* to) const;
  double motionTime(const ArmState& from, const ArmState& to, const ArmMotion& motion) const;

  Eigen::Isometry3d baseToWorld(const Eigen::Vector3d& base) const;  // upright or upside down
  Eigen::Isometry3d cameraPose(const ArmState& state) const;        // camera frame (z forward) in the world
  std::vector<Capsule> worldCapsules(const ArmState& state) const;  // ur5e::Link order, then the pole
  bool collides(const ArmState& state, const DistanceField& obstacles) const;
  const DistanceField& plants() const { return plants_; }
  const RobotMount& mount() const { return mount_; }
  // Where a gantry's base may go from now on (a trolley that carried it along the row).
  void setBaseRange(const Eigen::Vector2d& xy_min, const Eigen::Vector2d& xy_max) {
    mount_.xy_min = xy_min;
    mount_.xy_max = xy_max;
  }

 private:
  RobotMount mount_;
  DistanceField plants_;
};

}  // namespace sim
}  // namespace fruit_shape_completion
