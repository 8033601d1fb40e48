#include <fruit_shape_completion/fruit_center.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace fruit_shape_completion {

namespace {
Eigen::Vector3d meanOf(const PointList& points) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  int n = 0;
  for (const auto& p : points)
    if (p.allFinite()) {
      mean += p;
      ++n;
    }
  return n > 0 ? Eigen::Vector3d(mean / n) : mean;
}

// The normal lines' least-squares system over the points with a finite normal: sum (I - n n^T)
// and sum (I - n n^T) p. The centre prior solves it; how firmly it holds is its weakest
// eigenvalue per line.
struct NormalLines {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  int used = 0;
};

NormalLines normalLines(const PointList& points, const std::vector<Eigen::Vector3d>& normals) {
  NormalLines lines;
  for (size_t i = 0; i < points.size() && i < normals.size(); ++i) {
    if (!points[i].allFinite() || !normals[i].allFinite()) continue;
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - normals[i] * normals[i].transpose();
    lines.A += P;
    lines.rhs += P * points[i];
    ++lines.used;
  }
  return lines;
}

Eigen::Vector3d centerOf(const NormalLines& lines, const Eigen::Vector3d& mean, double lambda) {
  if (lines.used == 0) return mean;
  const Eigen::Matrix3d A = lines.A + lambda * Eigen::Matrix3d::Identity();
  const Eigen::Vector3d rhs = lines.rhs + lambda * mean;
  const Eigen::Vector3d w = A.ldlt().solve(rhs);
  return w.allFinite() ? w : mean;
}

// The RMS distance of the normal lines from w.
double lineSpread(const PointList& points, const std::vector<Eigen::Vector3d>& normals, const Eigen::Vector3d& w) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < points.size() && i < normals.size(); ++i) {
    if (!points[i].allFinite() || !normals[i].allFinite()) continue;
    const Eigen::Vector3d d = w - points[i];
    sum += (d - d.dot(normals[i]) * normals[i]).squaredNorm();
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

double holdOf(const NormalLines& lines) {
  if (lines.used == 0) return 0.0;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(lines.A / lines.used, Eigen::EigenvaluesOnly);
  return std::max(0.0, es.eigenvalues()(0));
}
}  // namespace

Eigen::Vector3d estimateFruitCenter(const PointList& points,
                                    const std::vector<Eigen::Vector3d>& normals, double lambda) {
  return centerOf(normalLines(points, normals), meanOf(points), lambda);
}

SphereFit fitSphere(const PointList& points) {
  SphereFit fit;
  const Eigen::Vector3d mean = meanOf(points);
  // Relative to the mean: |q|^2 = 2 q.c' + (r^2 - |c'|^2) is linear in c' and the constant.
  Eigen::Matrix4d A = Eigen::Matrix4d::Zero();
  Eigen::Vector4d rhs = Eigen::Vector4d::Zero();
  int n = 0;
  for (const auto& p : points) {
    if (!p.allFinite()) continue;
    const Eigen::Vector3d q = p - mean;
    const Eigen::Vector4d row(2.0 * q.x(), 2.0 * q.y(), 2.0 * q.z(), 1.0);
    A += row * row.transpose();
    rhs += row * q.squaredNorm();
    ++n;
  }
  if (n < 4) return fit;
  // A's upper left block is 4 sum q q^T: the points' spread, whose eigenvalues tell a flat patch.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> shape;
  shape.computeDirect(Eigen::Matrix3d(A.topLeftCorner<3, 3>()), Eigen::EigenvaluesOnly);
  if (!(shape.eigenvalues()(0) > 0.05 * 0.05 * shape.eigenvalues()(2))) return fit;  // flat or a line
  const Eigen::Vector4d x = A.ldlt().solve(rhs);
  const Eigen::Vector3d offset = x.head<3>();
  const double r2 = x(3) + offset.squaredNorm();
  if (!x.allFinite() || offset.norm() > 0.08 || !(r2 > 0.0)) return fit;
  fit.center = mean + offset;
  fit.radius = std::sqrt(r2);
  return fit;
}

double normalLineHold(const PointList& points, const std::vector<Eigen::Vector3d>& normals) {
  return holdOf(normalLines(points, normals));
}

Eigen::Vector3d limitToSeenDepth(const PointList& points, const std::vector<Eigen::Vector3d>& normals,
                                 const Eigen::Vector3d& center, double margin) {
  if (!(margin >= 0.0) || !center.allFinite()) return center;
  Eigen::Vector3d inward = Eigen::Vector3d::Zero();
  int with_normal = 0;
  for (std::size_t i = 0; i < points.size() && i < normals.size(); ++i)
    if (points[i].allFinite() && normals[i].allFinite()) {
      inward += normals[i];
      ++with_normal;
    }
  if (with_normal < 10 || !(inward.norm() > 1e-9)) return center;
  inward.normalize();
  std::vector<double> depth;
  depth.reserve(points.size());
  for (const auto& p : points)
    if (p.allFinite()) depth.push_back(p.dot(inward));
  // The 99th percentile: a few strays behind the fruit do not move the outline.
  const auto deepest = depth.begin() + static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(depth.size() - 1));
  std::nth_element(depth.begin(), deepest, depth.end());
  const double beyond = center.dot(inward) - (*deepest + margin);
  return beyond > 0.0 ? Eigen::Vector3d(center - beyond * inward) : center;
}

Eigen::Vector3d blendedFruitCenter(const PointList& points, const std::vector<Eigen::Vector3d>& normals,
                                   double lambda, const CenterPriorBlend& blend) {
  const NormalLines system = normalLines(points, normals);
  const Eigen::Vector3d lines = centerOf(system, meanOf(points), lambda);
  auto ramp = [](double value, double full, double none) {  // 1 at or beyond `full`, 0 at `none`
    if (full == none) return value <= full ? 1.0 : 0.0;
    return std::clamp((none - value) / (none - full), 0.0, 1.0);
  };
  Eigen::Vector3d center = lines;
  if (const double hold_weight = ramp(holdOf(system), blend.sphere_below, blend.normals_above); hold_weight > 0.0) {
    const SphereFit sphere = fitSphere(points);
    const double w = sphere.valid() ? hold_weight * ramp(sphere.radius, blend.sphere_radius_full, blend.sphere_radius_none) : 0.0;
    if (w > 0.0) center = w * sphere.center + (1.0 - w) * lines;
  }
  // Lines that meet where they were aimed (a sphere-like fruit) put the prior where it belongs
  // even when what was seen ends in front of the centre; lines that scatter (lobes, steep
  // sides) leave it free to slide along the view.
  if (!(blend.rim_margin >= 0.0) || lineSpread(points, normals, lines) < blend.rim_min_line_spread) return center;
  return limitToSeenDepth(points, normals, center, blend.rim_margin);
}

ClusterShapeCheck checkClusterShape(const PointList& points,
                                    const std::vector<Eigen::Vector3d>& normals) {
  ClusterShapeCheck check;
  const Eigen::Vector3d mean = meanOf(points);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  int n = 0;
  for (const auto& p : points)
    if (p.allFinite()) {
      cov += (p - mean) * (p - mean).transpose();
      ++n;
    }
  if (n < 10) {
    check.ok = false;
    check.reason = "fewer than 10 finite points";
    return check;
  }
  cov /= n;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  const double spread_mid = std::sqrt(std::max(0.0, es.eigenvalues()(1)));
  if (spread_mid < 0.003) {
    std::ostringstream os;
    os << "collinear cluster: points spread only " << spread_mid * 1000.0
       << " mm across their main direction";
    check.ok = false;
    check.reason = os.str();
    return check;
  }
  // Second moment of the normals: one dominant direction means a flat patch.
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  int m = 0;
  for (const auto& nn : normals)
    if (nn.allFinite()) {
      M += nn * nn.transpose();
      ++m;
    }
  if (m < 10) {
    std::ostringstream os;
    os << "only " << m << " points have a usable surface normal";
    check.ok = false;
    check.reason = os.str();
    return check;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> ns(M / m);
  if (ns.eigenvalues()(1) < 0.01) {
    check.ok = false;
    check.reason = "planar cluster: surface normals are nearly parallel, no curvature to fit";
  }
  return check;
}

}  // namespace fruit_shape_completion
