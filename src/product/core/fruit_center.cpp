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
}  // namespace

Eigen::Vector3d estimateFruitCenter(const PointList& points,
                                    const std::vector<Eigen::Vector3d>& normals, double lambda) {
  const Eigen::Vector3d mean = meanOf(points);
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  int used = 0;
  for (size_t i = 0; i < points.size() && i < normals.size(); ++i) {
    if (!points[i].allFinite() || !normals[i].allFinite()) continue;
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - normals[i] * normals[i].transpose();
    A += P;
    rhs += P * points[i];
    ++used;
  }
  if (used == 0) return mean;
  A += lambda * Eigen::Matrix3d::Identity();
  rhs += lambda * mean;
  const Eigen::Vector3d w = A.ldlt().solve(rhs);
  return w.allFinite() ? w : mean;
}

Eigen::Vector3d sphereCenter(const PointList& points) {
  const Eigen::Vector3d none = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
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
  if (n < 4) return none;
  // Points in a plane or on a line leave a direction of A free.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(A);
  if (!(es.eigenvalues()(0) > 1e-9 * es.eigenvalues()(3))) return none;
  const Eigen::Vector4d x = es.eigenvectors() * (es.eigenvectors().transpose() * rhs).cwiseQuotient(es.eigenvalues());
  const Eigen::Vector3d offset = x.head<3>();
  if (!offset.allFinite() || offset.norm() > 0.08) return none;
  return mean + offset;
}

double normalLineHold(const std::vector<Eigen::Vector3d>& normals) {
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  int n = 0;
  for (const auto& nn : normals)
    if (nn.allFinite()) {
      M += Eigen::Matrix3d::Identity() - nn * nn.transpose();
      ++n;
    }
  if (n == 0) return 0.0;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(M / n, Eigen::EigenvaluesOnly);
  return std::max(0.0, es.eigenvalues()(0));
}

Eigen::Vector3d blendedFruitCenter(const PointList& points, const std::vector<Eigen::Vector3d>& normals,
                                   double lambda, const CenterPriorBlend& blend) {
  const Eigen::Vector3d lines = estimateFruitCenter(points, normals, lambda);
  const double span = blend.normals_above - blend.sphere_below;
  const double hold = normalLineHold(normals);
  const double w = span > 0.0 ? std::clamp((blend.normals_above - hold) / span, 0.0, 1.0)
                              : (hold <= blend.sphere_below ? 1.0 : 0.0);
  if (w <= 0.0) return lines;
  const Eigen::Vector3d sphere = sphereCenter(points);
  if (!sphere.allFinite()) return lines;
  return w * sphere + (1.0 - w) * lines;
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
