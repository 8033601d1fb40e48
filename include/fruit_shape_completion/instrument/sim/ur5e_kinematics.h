#pragma once
// The UR5e arm from its published Denavit-Hartenberg parameters: forward kinematics, the
// closed-form inverse (up to 8 solutions), joint limits, and capsules around its links for
// collision tests. Frames follow the DH convention: base z up along joint 1, flange z along
// the tool axis.
#include <Eigen/Geometry>

#include <array>
#include <vector>

namespace fruit_shape_completion {
namespace sim {

using JointVector = Eigen::Matrix<double, 6, 1>;

// A segment swept by a sphere.
struct Capsule {
  Eigen::Vector3d a, b;
  double radius = 0.0;
};
// Distance between two segments' closest points (0 if they cross).
double segmentDistance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& q0,
                       const Eigen::Vector3d& q1);
inline bool intersects(const Capsule& a, const Capsule& b) {
  return segmentDistance(a.a, a.b, b.a, b.b) < a.radius + b.radius;
}

namespace ur5e {
// Universal Robots' DH parameters for the UR5e [m, rad].
constexpr double kD1 = 0.1625, kA2 = -0.425, kA3 = -0.3922, kD4 = 0.1333, kD5 = 0.0997, kD6 = 0.0996;
// ur_description's limits: every joint +-2 pi except the elbow, +-pi (the arm would fold into
// itself); rated speed 180 deg/s on every joint.
constexpr double kMaxVelocity = 3.14159265358979;  // [rad/s]
JointVector lowerLimits();
JointVector upperLimits();
bool withinLimits(const JointVector& q);

// Frames 0 (base) to 6 (flange) in the base frame.
std::array<Eigen::Isometry3d, 7> linkFrames(const JointVector& q);
Eigen::Isometry3d flangePose(const JointVector& q);

// All joint vectors (angles in (-pi, pi]) that put the flange at `flange` (base frame). At the
// wrist singularity (joint 5 at 0 or pi) joint 6 is not determined; it takes `q6_if_free`.
std::vector<JointVector> inverse(const Eigen::Isometry3d& flange, double q6_if_free = 0.0);

// The vector equal to q modulo 2 pi per joint that is nearest `reference` within the limits;
// false if some joint has no such angle.
bool nearestWithinLimits(const JointVector& q, const JointVector& reference, JointVector* out);

// Capsules around the links, in the base frame: shoulder, upper arm, forearm, wrist 1-3 and a
// camera body across the flange. The upper arm and forearm sit off the DH plane, as the real
// arm's links do.
enum Link { kShoulder, kUpperArm, kForearm, kWrist1, kWrist2, kWrist3, kCamera, kLinkCount };
std::array<Capsule, kLinkCount> linkCapsules(const JointVector& q);
}  // namespace ur5e

}  // namespace sim
}  // namespace fruit_shape_completion
