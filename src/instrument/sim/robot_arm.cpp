#include <fruit_shape_completion/instrument/sim/robot_arm.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace fruit_shape_completion {
namespace sim {

std::string ArmMotion::problem() const {
  for (double v : {velocity_scaling, acceleration_scaling})
    if (!(v > 0.0 && v <= 1.0)) return "velocity and acceleration scaling must be in (0, 1]";
  for (double v : {joint_velocity, joint_acceleration, gantry_velocity, gantry_acceleration})
    if (!(std::isfinite(v) && v > 0.0)) return "arm velocities and accelerations must be > 0";
  return {};
}

RobotArm::RobotArm(const Scene& scene, double collision_resolution) : mount_(scene.robot) {
  if (mount_.kind == RobotMount::Kind::kNone) throw std::invalid_argument("the scene has no arm (robot mount none)");
  if (!(collision_resolution > 0.0 && collision_resolution < 1.0))
    throw std::invalid_argument("collision resolution must be in (0, 1) m");
  plants_ = DistanceField::ofTriangles(scene.vertices, scene.triangles, collision_resolution, 0.2);
}

Eigen::Isometry3d RobotArm::baseToWorld(const Eigen::Vector3d& base) const {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = base;
  if (mount_.kind == RobotMount::Kind::kGantry) t.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return t;
}

Eigen::Isometry3d RobotArm::cameraPose(const ArmState& s) const {
  Eigen::Isometry3d t = baseToWorld(s.base) * ur5e::flangePose(s.q);
  t.translation() += kCameraOffset * t.linear().col(2);
  return t;
}

std::vector<Capsule> RobotArm::worldCapsules(const ArmState& s) const {
  const Eigen::Isometry3d tb = baseToWorld(s.base);
  std::vector<Capsule> out;
  for (const Capsule& c : ur5e::linkCapsules(s.q)) out.push_back({tb * c.a, tb * c.b, c.radius});
  // The pole: from the floor up to the base, or from the base up to the gantry.
  const Eigen::Vector3d end = mount_.kind == RobotMount::Kind::kPole
                                  ? Eigen::Vector3d(s.base.x(), s.base.y(), 0.0)
                                  : Eigen::Vector3d(s.base.x(), s.base.y(), mount_.top + 0.2);
  out.push_back({s.base, end, mount_.pole_radius});
  return out;
}

bool RobotArm::collides(const ArmState& s, const DistanceField& obstacles) const {
  const std::vector<Capsule> c = worldCapsules(s);
  const Capsule& pole = c.back();
  for (int l = ur5e::kUpperArm; l < ur5e::kLinkCount; ++l)
    if (obstacles.hits(c[l]) || intersects(c[l], pole)) return true;
  if (obstacles.hits(pole)) return true;
  // The arm folding onto itself: wrist and camera against the shoulder, camera against the upper arm.
  for (int l : {ur5e::kWrist2, ur5e::kWrist3, ur5e::kCamera})
    if (intersects(c[l], c[ur5e::kShoulder])) return true;
  return intersects(c[ur5e::kCamera], c[ur5e::kUpperArm]);
}

double RobotArm::motionTime(const ArmState& from, const ArmState& to, const ArmMotion& m) const {
  auto axis = [](double dist, double v, double a) {
    dist = std::abs(dist);
    return dist >= v * v / a ? dist / v + v / a : 2.0 * std::sqrt(dist / a);
  };
  const double jv = m.joint_velocity * m.velocity_scaling, ja = m.joint_acceleration * m.acceleration_scaling;
  const double gv = m.gantry_velocity * m.velocity_scaling, ga = m.gantry_acceleration * m.acceleration_scaling;
  double t = 0.0;
  for (int i = 0; i < 6; ++i) t = std::max(t, axis(to.q[i] - from.q[i], jv, ja));
  for (int i = 0; i < 3; ++i) t = std::max(t, axis(to.base[i] - from.base[i], gv, ga));
  return t;
}

RobotArm::Reach RobotArm::reach(const PinholeCamera& camera, const ArmState& from, const ArmMotion& motion,
                                const DistanceField& obstacles, ArmState* to) const {
  Eigen::Isometry3d flange = Eigen::Isometry3d::Identity();
  flange.linear() = camera.rotation;
  flange.translation() = camera.position - kCameraOffset * camera.rotation.col(2);
  std::vector<Eigen::Vector3d> bases;
  if (mount_.kind == RobotMount::Kind::kPole) {
    bases.push_back(mount_.base);
  } else {
    auto clamp = [&](Eigen::Vector2d xy, double drop) {
      xy = xy.cwiseMax(mount_.xy_min).cwiseMin(mount_.xy_max);
      return Eigen::Vector3d(xy.x(), xy.y(), mount_.top - std::clamp(drop, 0.0, mount_.max_drop));
    };
    bases.push_back(clamp(from.base.head<2>(), mount_.top - from.base.z()));
    // Bases behind the camera (opposite its view), at a few distances, bearings and heights.
    const Eigen::Vector3d d = camera.rotation.col(2);
    Eigen::Vector2d back(-d.x(), -d.y());
    if (back.norm() < 0.2) back = from.base.head<2>() - camera.position.head<2>();
    back = back.norm() > 1e-6 ? back.normalized() : Eigen::Vector2d(1, 0);
    for (double r : {0.15, 0.35, 0.55})
      for (double bearing : {0.0, 0.9, -0.9})
        for (double f : {0.0, 0.5, 1.0})
          bases.push_back(clamp(camera.position.head<2>() + r * (Eigen::Rotation2Dd(bearing) * back), f * mount_.max_drop));
  }
  bool any_inverse = false, any_within_limits = false, found = false;
  double best = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& base : bases) {
    const Eigen::Isometry3d in_base = baseToWorld(base).inverse() * flange;
    for (const JointVector& sol : ur5e::inverse(in_base, from.q[5])) {
      any_inverse = true;
      ArmState s{base, JointVector::Zero()};
      if (!ur5e::nearestWithinLimits(sol, from.q, &s.q)) continue;
      any_within_limits = true;
      const double t = motionTime(from, s, motion);
      if (t >= best || collides(s, obstacles)) continue;
      best = t;
      *to = s;
      found = true;
    }
  }
  if (found) return Reach::kReached;
  if (!any_inverse) return Reach::kNoInverse;
  return any_within_limits ? Reach::kCollision : Reach::kJointLimits;
}

}  // namespace sim
}  // namespace fruit_shape_completion
