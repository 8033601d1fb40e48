#include <fruit_shape_completion/sim/robot_arm.h>

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

const char* toString(RobotArm::Reach r) {
  switch (r) {
    case RobotArm::Reach::kReached: return "reached";
    case RobotArm::Reach::kNoInverse: return "no inverse kinematics";
    case RobotArm::Reach::kJointLimits: return "beyond the joint limits";
    case RobotArm::Reach::kCollision: return "collision";
  }
  return "?";
}

// Euclidean distance transform of the plants' triangles on a grid: distance from each cell's
// centre to the nearest cell a triangle passes through.
struct RobotArm::Field {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  double resolution = 0.01, margin = 0.0;
  Eigen::Vector3i size = Eigen::Vector3i::Zero();
  std::vector<float> distance;

  double at(const Eigen::Vector3d& p) const {
    if (distance.empty()) return std::numeric_limits<double>::infinity();
    const Eigen::Vector3d g = (p - origin) / resolution;
    if (!g.allFinite()) return 0.0;
    const Eigen::Vector3i c = g.array().floor().cast<int>();
    if ((c.array() < 0).any() || (c.array() >= size.array()).any()) return margin;  // beyond: further than margin
    return distance[(static_cast<std::size_t>(c.z()) * size.y() + c.y()) * size.x() + c.x()];
  }

  // Felzenszwalb and Huttenlocher's lower envelope of parabolas, along one grid line.
  static void transform1d(std::vector<double>& f, std::vector<double>& d, std::vector<int>& v, std::vector<double>& z) {
    const int n = static_cast<int>(f.size());
    int k = 0;
    v[0] = 0;
    z[0] = -std::numeric_limits<double>::infinity();
    z[1] = std::numeric_limits<double>::infinity();
    auto meet = [&](int q, int p) { return ((f[q] + double(q) * q) - (f[p] + double(p) * p)) / (2.0 * q - 2.0 * p); };
    for (int q = 1; q < n; ++q) {
      double s = meet(q, v[k]);
      while (s <= z[k]) s = meet(q, v[--k]);  // z[0] is -inf: k stays >= 0
      ++k;
      v[k] = q;
      z[k] = s;
      z[k + 1] = std::numeric_limits<double>::infinity();
    }
    k = 0;
    for (int q = 0; q < n; ++q) {
      while (z[k + 1] < q) ++k;
      d[q] = double(q - v[k]) * (q - v[k]) + f[v[k]];
    }
  }

  void build(const Scene& scene, double res, double border) {
    margin = border;
    if (scene.triangles.empty()) return;
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const auto& t : scene.triangles)
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d p = scene.vertices[static_cast<std::size_t>(t[k])].cast<double>();
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
    lo.array() -= border;
    hi.array() += border;
    // Coarser cells rather than an unbounded grid for a sprawling scene.
    resolution = std::max(res, std::cbrt((hi - lo).prod() / 6.4e7));
    origin = lo;
    size = ((hi - lo) / resolution).array().ceil().cast<int>() + 1;
    const std::size_t n = static_cast<std::size_t>(size.x()) * size.y() * size.z();
    constexpr double kFar = 1e20;
    std::vector<double> sq(n, kFar);
    auto index = [&](int x, int y, int z) { return (static_cast<std::size_t>(z) * size.y() + y) * size.x() + x; };
    for (const auto& t : scene.triangles) {
      const Eigen::Vector3d a = scene.vertices[static_cast<std::size_t>(t[0])].cast<double>();
      const Eigen::Vector3d b = scene.vertices[static_cast<std::size_t>(t[1])].cast<double>();
      const Eigen::Vector3d c = scene.vertices[static_cast<std::size_t>(t[2])].cast<double>();
      const double longest = std::max({(b - a).norm(), (c - a).norm(), (c - b).norm()});
      const int steps = std::max(1, static_cast<int>(std::ceil(longest / (0.5 * resolution))));
      for (int i = 0; i <= steps; ++i)
        for (int j = 0; i + j <= steps; ++j) {
          const Eigen::Vector3d p = a + (b - a) * (double(i) / steps) + (c - a) * (double(j) / steps);
          const Eigen::Vector3i g = ((p - origin) / resolution).array().floor().cast<int>();
          sq[index(g.x(), g.y(), g.z())] = 0.0;
        }
    }
    const int longest_axis = size.maxCoeff();
    std::vector<double> f(static_cast<std::size_t>(longest_axis)), d(f.size()), z(f.size() + 1);
    std::vector<int> v(f.size());
    for (int axis = 0; axis < 3; ++axis) {
      const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
      f.resize(static_cast<std::size_t>(size[axis]));
      d.resize(f.size());
      for (int i = 0; i < size[a1]; ++i)
        for (int j = 0; j < size[a2]; ++j) {
          Eigen::Vector3i c;
          c[a1] = i;
          c[a2] = j;
          for (int k = 0; k < size[axis]; ++k) {
            c[axis] = k;
            f[static_cast<std::size_t>(k)] = sq[index(c.x(), c.y(), c.z())];
          }
          transform1d(f, d, v, z);
          for (int k = 0; k < size[axis]; ++k) {
            c[axis] = k;
            sq[index(c.x(), c.y(), c.z())] = std::min(d[static_cast<std::size_t>(k)], kFar);
          }
        }
    }
    distance.resize(n);
    for (std::size_t i = 0; i < n; ++i) distance[i] = static_cast<float>(std::sqrt(sq[i]) * resolution);
  }

  // A capsule is taken as touching the plants when some point of its axis is nearer than its
  // radius, to within a cell.
  bool hits(const Capsule& c) const {
    if (distance.empty()) return false;
    const double len = (c.b - c.a).norm();
    const int steps = std::max(1, static_cast<int>(std::ceil(len / (0.5 * resolution))));
    for (int i = 0; i <= steps; ++i)
      if (at(c.a + (c.b - c.a) * (double(i) / steps)) < c.radius + 0.5 * resolution) return true;
    return false;
  }
};

RobotArm::RobotArm(const Scene& scene, double collision_resolution) : mount_(scene.robot), field_(new Field) {
  if (mount_.kind == RobotMount::Kind::kNone) throw std::invalid_argument("the scene has no arm (robot mount none)");
  if (!(collision_resolution > 0.0 && collision_resolution < 1.0))
    throw std::invalid_argument("collision resolution must be in (0, 1) m");
  field_->build(scene, collision_resolution, 0.2);
}

RobotArm::~RobotArm() = default;

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

double RobotArm::plantDistance(const Eigen::Vector3d& p) const { return field_->at(p); }

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

bool RobotArm::collides(const ArmState& s) const {
  const std::vector<Capsule> c = worldCapsules(s);
  const Capsule& pole = c.back();
  for (int l = ur5e::kUpperArm; l < ur5e::kLinkCount; ++l)
    if (field_->hits(c[l]) || intersects(c[l], pole)) return true;
  if (field_->hits(pole)) return true;
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
                                ArmState* to) const {
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
      if (t >= best || collides(s)) continue;
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
