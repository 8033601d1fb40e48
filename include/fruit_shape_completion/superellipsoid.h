#pragma once
// A posed superellipsoid: shape (a, b, c, e1, e2) and pose (translation + roll/pitch/yaw).
//
// Implicit function in the shape's own frame:
//   f(x,y,z) = ((x/a)^(2/e2) + (y/b)^(2/e2))^(e2/e1) + (z/c)^(2/e1)
// f < 1 inside, f = 1 on the surface, f > 1 outside.
//
// THE pose convention (fitting, sampling, markers and messages all use this one):
//   p_world = t + R * p_local,   R = Rz(yaw) * Ry(pitch) * Rx(roll)
// angles in radians; this is the ROS/tf2 convention (tf2::Quaternion::setRPY, fixed axes X, Y, Z).
#include <fruit_shape_completion/types.h>

#include <Eigen/Geometry>
#include <cmath>

namespace fruit_shape_completion {

struct Superellipsoid {
  double a = 0.05, b = 0.05, c = 0.05;  // semi-axes along local x, y, z [m]
  double e1 = 0.5, e2 = 0.5;            // e1: squareness along z, e2: in the xy plane
  Eigen::Vector3d t = Eigen::Vector3d::Zero();    // centre [m]
  Eigen::Vector3d rpy = Eigen::Vector3d::Zero();  // roll, pitch, yaw [rad]

  static Superellipsoid sphere(double radius, const Eigen::Vector3d& center);

  Eigen::Matrix3d rotation() const;
  Eigen::Vector3d toLocal(const Eigen::Vector3d& p_world) const;
  Eigen::Vector3d toWorld(const Eigen::Vector3d& p_local) const;

  // Implicit function of a local point.
  double implicitLocal(const Eigen::Vector3d& p_local) const;
  // Implicit function of a world point.
  double implicit(const Eigen::Vector3d& p_world) const { return implicitLocal(toLocal(p_world)); }
  bool isInside(const Eigen::Vector3d& p_world) const { return implicit(p_world) <= 1.0; }

  // Radial distance: |r0| * |1 - f^(-e1/2)|, r0 the point in the local frame. Distance from
  // the point to the surface along the ray from the centre.
  double radialDistance(const Eigen::Vector3d& p_world) const;

  // Surface point in the direction of a local vector u (u need not be unit).
  Eigen::Vector3d surfacePointLocal(const Eigen::Vector3d& u) const;

  // V = 2 a b c e1 e2 B(e1/2 + 1, e1) B(e2/2, e2/2).
  double volume() const;

  // n near-uniform directions (Fibonacci sphere) projected radially onto the surface, world frame.
  PointList sampleSurface(int n) const;

  bool isFinite() const;
};

// Rotation of the convention above, templated so Ceres cost functors share it.
template <typename T>
inline void rpyToRotation(const T* rpy, T R[9]) {
  using std::cos;
  using std::sin;
  const T cr = cos(rpy[0]), sr = sin(rpy[0]);
  const T cp = cos(rpy[1]), sp = sin(rpy[1]);
  const T cy = cos(rpy[2]), sy = sin(rpy[2]);
  // Row-major R = Rz(yaw) * Ry(pitch) * Rx(roll).
  R[0] = cy * cp; R[1] = cy * sp * sr - sy * cr; R[2] = cy * sp * cr + sy * sr;
  R[3] = sy * cp; R[4] = sy * sp * sr + cy * cr; R[5] = sy * sp * cr - cy * sr;
  R[6] = -sp;     R[7] = cp * sr;                R[8] = cp * cr;
}

// Implicit function in the local frame for squared coordinates, templated for Ceres.
// A tiny epsilon keeps pow() differentiable in the exponent at a zero coordinate.
template <typename T>
inline T superellipsoidImplicit(const T& x, const T& y, const T& z, const T& a, const T& b,
                                const T& c, const T& e1, const T& e2) {
  using std::pow;
  const double eps = 1e-18;
  const T xx = x * x / (a * a) + eps;
  const T yy = y * y / (b * b) + eps;
  const T zz = z * z / (c * c) + eps;
  return pow(pow(xx, 1.0 / e2) + pow(yy, 1.0 / e2), e2 / e1) + pow(zz, 1.0 / e1);
}

// n near-uniform unit directions on the sphere (Fibonacci lattice).
PointList fibonacciSphere(int n);

}  // namespace fruit_shape_completion
