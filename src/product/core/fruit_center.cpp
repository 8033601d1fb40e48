#include <fruit_shape_completion/fruit_center.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
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
