#include <fruit_shape_completion/instrument/sim/ur5e_kinematics.h>

#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {
namespace sim {

double segmentDistance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& q0,
                       const Eigen::Vector3d& q1) {
  // Closest points of two segments: minimise |p0 + s u - q0 - t v| over s, t in [0, 1].
  const Eigen::Vector3d u = p1 - p0, v = q1 - q0, w = p0 - q0;
  const double a = u.dot(u), b = u.dot(v), c = v.dot(v), d = u.dot(w), e = v.dot(w);
  const double den = a * c - b * b;
  double s = 0.0, t = 0.0;
  if (a < 1e-18 && c < 1e-18) return w.norm();
  if (a < 1e-18) {
    t = std::clamp(e / c, 0.0, 1.0);
  } else if (c < 1e-18) {
    s = std::clamp(-d / a, 0.0, 1.0);
  } else {
    s = den > 1e-12 * a * c ? std::clamp((b * e - c * d) / den, 0.0, 1.0) : 0.0;
    t = (b * s + e) / c;
    if (t < 0.0) {
      t = 0.0;
      s = std::clamp(-d / a, 0.0, 1.0);
    } else if (t > 1.0) {
      t = 1.0;
      s = std::clamp((b - d) / a, 0.0, 1.0);
    }
  }
  return (w + s * u - t * v).norm();
}

namespace ur5e {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr std::array<double, 6> kD{kD1, 0.0, 0.0, kD4, kD5, kD6};
constexpr std::array<double, 6> kA{0.0, kA2, kA3, 0.0, 0.0, 0.0};
constexpr std::array<double, 6> kAlpha{kPi / 2, 0.0, 0.0, kPi / 2, -kPi / 2, 0.0};

// Rz(theta) Tz(d) Tx(a) Rx(alpha).
Eigen::Isometry3d dh(int i, double theta) {
  const double ct = std::cos(theta), st = std::sin(theta);
  const double ca = std::cos(kAlpha[i]), sa = std::sin(kAlpha[i]);
  Eigen::Matrix4d m;
  m << ct, -st * ca, st * sa, kA[i] * ct,  //
      st, ct * ca, -ct * sa, kA[i] * st,   //
      0, sa, ca, kD[i],                    //
      0, 0, 0, 1;
  return Eigen::Isometry3d(m);
}

double wrap(double a) {
  a = std::fmod(a + kPi, 2 * kPi);
  if (a <= 0) a += 2 * kPi;
  return a - kPi;
}

}  // namespace

JointVector lowerLimits() { return -upperLimits(); }
JointVector upperLimits() {
  JointVector u = JointVector::Constant(2 * kPi);
  u[2] = kPi;
  return u;
}
bool withinLimits(const JointVector& q) {
  return ((q.array() >= lowerLimits().array()) && (q.array() <= upperLimits().array())).all();
}

std::array<Eigen::Isometry3d, 7> linkFrames(const JointVector& q) {
  std::array<Eigen::Isometry3d, 7> f;
  f[0] = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 6; ++i) f[i + 1] = f[i] * dh(i, q[i]);
  return f;
}

Eigen::Isometry3d flangePose(const JointVector& q) { return linkFrames(q)[6]; }

std::vector<JointVector> inverse(const Eigen::Isometry3d& flange, double q6_if_free) {
  std::vector<JointVector> out;
  const Eigen::Vector3d p6 = flange.translation();
  const Eigen::Matrix3d r = flange.linear();
  // Joints 2-4 turn about parallel axes (z1), so the wrist centre's offset along z1 is d4.
  const Eigen::Vector3d p5 = p6 - kD6 * r.col(2);
  const double radius = std::hypot(p5.x(), p5.y());
  if (!(radius >= std::abs(kD4)) || !std::isfinite(radius)) return out;
  const double phi = std::atan2(p5.y(), p5.x()), off = std::asin(kD4 / radius);
  for (const double q1 : {phi + off, phi + kPi - off}) {
    const Eigen::Vector3d z1(std::sin(q1), -std::cos(q1), 0.0);
    // The flange's offset along z1 is d4 + d6 cos(q5).
    double c5 = (p6.dot(z1) - kD4) / kD6;
    if (std::abs(c5) > 1.0 + 1e-9) continue;
    c5 = std::clamp(c5, -1.0, 1.0);
    for (const double q5 : {std::acos(c5), -std::acos(c5)}) {
      const double s5 = std::sin(q5);
      // z1 seen from the flange is (s5 c6, -s5 s6, c5).
      const double q6 = std::abs(s5) < 1e-9 ? q6_if_free
                                             : std::atan2(-r.col(1).dot(z1) / s5, r.col(0).dot(z1) / s5);
      const Eigen::Isometry3d t14 = dh(0, q1).inverse() * flange * (dh(4, q5) * dh(5, q6)).inverse();
      const double x = t14.translation().x(), y = t14.translation().y();
      double c3 = (x * x + y * y - kA2 * kA2 - kA3 * kA3) / (2 * kA2 * kA3);
      if (std::abs(c3) > 1.0 + 1e-9) continue;
      c3 = std::clamp(c3, -1.0, 1.0);
      for (const double q3 : {std::acos(c3), -std::acos(c3)}) {
        const double q2 = std::atan2(y, x) - std::atan2(kA3 * std::sin(q3), kA2 + kA3 * std::cos(q3));
        const double q234 = std::atan2(t14.linear()(1, 0), t14.linear()(0, 0));
        JointVector q;
        q << wrap(q1), wrap(q2), wrap(q3), wrap(q234 - q2 - q3), wrap(q5), wrap(q6);
        out.push_back(q);
      }
    }
  }
  return out;
}

bool nearestWithinLimits(const JointVector& q, const JointVector& reference, JointVector* out) {
  const JointVector lo = lowerLimits(), hi = upperLimits();
  for (int i = 0; i < 6; ++i) {
    double a = reference[i] + wrap(q[i] - reference[i]);
    if (a > hi[i]) a -= 2 * kPi;
    if (a < lo[i]) a += 2 * kPi;
    if (a < lo[i] || a > hi[i]) return false;
    (*out)[i] = a;
  }
  return true;
}

std::array<Capsule, kLinkCount> linkCapsules(const JointVector& q) {
  const auto f = linkFrames(q);
  auto o = [&](int i) -> Eigen::Vector3d { return f[i].translation(); };
  const Eigen::Vector3d z1 = f[1].linear().col(2);
  // The real upper arm runs 13.8 cm along z1 from the DH plane, the forearm 0.7 cm.
  constexpr double kUpperArmOffset = 0.138, kForearmOffset = 0.007;
  const Eigen::Vector3d x6 = f[6].linear().col(0), z6 = f[6].linear().col(2);
  std::array<Capsule, kLinkCount> c;
  c[kShoulder] = {o(0), o(1), 0.075};
  c[kUpperArm] = {o(1) + kUpperArmOffset * z1, o(2) + kUpperArmOffset * z1, 0.06};
  c[kForearm] = {o(2) + kForearmOffset * z1, o(3) + kForearmOffset * z1, 0.05};
  c[kWrist1] = {o(3) + kForearmOffset * z1, o(4), 0.045};
  c[kWrist2] = {o(4), o(5), 0.045};
  c[kWrist3] = {o(5), o(6), 0.045};
  // A depth camera about 9 cm wide across the flange, its lens 2 cm beyond it.
  c[kCamera] = {o(6) + 0.015 * z6 - 0.045 * x6, o(6) + 0.015 * z6 + 0.045 * x6, 0.02};
  return c;
}

}  // namespace ur5e
}  // namespace sim
}  // namespace fruit_shape_completion
