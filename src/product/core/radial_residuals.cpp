#include <fruit_shape_completion/radial_residuals.h>

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>

namespace fruit_shape_completion {

namespace {

// Radial distances of all points in one cost function with an analytic Jacobian: the rotation
// and its derivatives are computed once per evaluation instead of once per point, and the
// powers are shared between value and derivatives (exp/log form). Residual i is
// |r0| (1 - F^(-e1/2)), signed so that its square is smooth; its magnitude is d_i.
// Parameter blocks: shape (a, b, c, e1, e2), translation (3), rpy (3).
class RadialResiduals : public ceres::CostFunction {
 public:
  explicit RadialResiduals(const std::vector<Point>& points) : P_(3, points.size()) {
    for (size_t i = 0; i < points.size(); ++i) P_.col(i) = points[i];
    set_num_residuals(static_cast<int>(points.size()));
    mutable_parameter_block_sizes()->assign({5, 3, 3});
  }

  // Column-wise Eigen array expressions, exp/log vectorised, over chunks of kChunk points whose
  // arrays live on the stack: the same arithmetic as over all points at once, without a heap
  // allocation per temporary and with the temporaries in L1.
  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const double* sh = params[0];
    const double* rpy = params[2];
    const double cr = std::cos(rpy[0]), sr = std::sin(rpy[0]);
    const double cp = std::cos(rpy[1]), sp = std::sin(rpy[1]);
    const double cy = std::cos(rpy[2]), sy = std::sin(rpy[2]);
    Eigen::Matrix3d Rx, Ry, Rz, dRx, dRy, dRz;
    Rx << 1, 0, 0, 0, cr, -sr, 0, sr, cr;
    Ry << cp, 0, sp, 0, 1, 0, -sp, 0, cp;
    Rz << cy, -sy, 0, sy, cy, 0, 0, 0, 1;
    dRx << 0, 0, 0, 0, -sr, -cr, 0, cr, -sr;
    dRy << -sp, 0, cp, 0, 0, 0, -cp, 0, -sp;
    dRz << -sy, -cy, 0, cy, -sy, 0, 0, 0, 0;
    Frame f;
    f.Rt = (Rz * Ry * Rx).transpose();
    if (jacobians != nullptr && jacobians[2] != nullptr) {  // only the angle Jacobian needs them
      f.dRt[0] = (Rz * Ry * dRx).transpose();
      f.dRt[1] = (Rz * dRy * Rx).transpose();
      f.dRt[2] = (dRz * Ry * Rx).transpose();
    }
    f.t = Eigen::Map<const Eigen::Vector3d>(params[1]);
    const Eigen::Index n = P_.cols();
    for (Eigen::Index i0 = 0; i0 < n; i0 += kChunk)
      evaluateChunk(sh, f, i0, std::min<Eigen::Index>(kChunk, n - i0), residuals, jacobians);
    return true;
  }

 private:
  static constexpr int kChunk = 64;
  struct Frame {
    Eigen::Matrix3d Rt, dRt[3];
    Eigen::Vector3d t;
  };

  // Points i0 .. i0 + m - 1.
  void evaluateChunk(const double* sh, const Frame& f, Eigen::Index i0, Eigen::Index m, double* residuals,
                     double** jacobians) const {
    const double a = sh[0], b = sh[1], c = sh[2], e1 = sh[3], e2 = sh[4];
    using Points = Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::ColMajor, 3, kChunk>;
    const Points Q = P_.middleCols(i0, m).colwise() - f.t;  // p - t
    // Coefficient products evaluated straight into their destination, no product temporary.
    const Points L = f.Rt.lazyProduct(Q);                   // local coordinates
    // The powers in single precision: four lanes per SSE register instead of two. Its relative
    // error of ~1e-7 is ~10 nm on a fruit's radius, far below the surface noise.
    using ArrayXf = Eigen::Array<float, Eigen::Dynamic, 1, Eigen::ColMajor, kChunk, 1>;
    const float eps = 1e-18f;
    const float ie1 = static_cast<float>(1.0 / e1), ie2 = static_cast<float>(1.0 / e2);
    const float e1f = static_cast<float>(e1), e2f = static_cast<float>(e2);
    // Column arrays (never mix Eigen row and column vectors in one coefficient-wise expression).
    const ArrayXf Lx = L.row(0).transpose().array().cast<float>();
    const ArrayXf Ly = L.row(1).transpose().array().cast<float>();
    const ArrayXf Lz = L.row(2).transpose().array().cast<float>();
    const ArrayXf x2 = Lx.square() + eps;
    const ArrayXf y2 = Ly.square() + eps;
    const ArrayXf z2 = Lz.square() + eps;
    const ArrayXf lx = x2.log() - static_cast<float>(std::log(a * a));
    const ArrayXf ly = y2.log() - static_cast<float>(std::log(b * b));
    const ArrayXf lz = z2.log() - static_cast<float>(std::log(c * c));
    const ArrayXf X = (lx * ie2).exp(), Y = (ly * ie2).exp(), Z = (lz * ie1).exp();
    const ArrayXf g = X + Y;
    const ArrayXf lg = g.log();
    const ArrayXf G = (lg * (e2f * ie1)).exp();
    const ArrayXf F = G + Z;
    const ArrayXf lF = F.log();
    const ArrayXf s = (lF * (-0.5f * e1f)).exp();
    const ArrayXf r = (x2 + y2 + z2).sqrt();
    Eigen::Map<Eigen::ArrayXd>(residuals + i0, m) = (r * (1.0f - s)).cast<double>();
    if (jacobians == nullptr) return;

    const ArrayXf dGdg = (e2f * ie1) * G / g;
    const ArrayXf k = 0.5f * e1f * r * s / F;  // -r * ds/dF
    // d residual / d local
    Points DL(3, m);
    const ArrayXf radial = (1.0f - s) / r;
    DL.row(0) = (Lx * (radial + k * dGdg * (2.0f * ie2) * X / x2)).cast<double>().matrix().transpose();
    DL.row(1) = (Ly * (radial + k * dGdg * (2.0f * ie2) * Y / y2)).cast<double>().matrix().transpose();
    DL.row(2) = (Lz * (radial + k * (2.0f * ie1) * Z / z2)).cast<double>().matrix().transpose();
    using RowMajorX = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    if (jacobians[0]) {
      Eigen::Map<RowMajorX> J(jacobians[0] + 5 * i0, m, 5);
      const float af = static_cast<float>(a), bf = static_cast<float>(b), cf = static_cast<float>(c);
      J.col(0) = (k * dGdg * (-2.0f * ie2 / af) * X).cast<double>().matrix();
      J.col(1) = (k * dGdg * (-2.0f * ie2 / bf) * Y).cast<double>().matrix();
      J.col(2) = (k * (-2.0f * ie1 / cf) * Z).cast<double>().matrix();
      // e1 enters G's exponent, Z's exponent and the exponent of s itself.
      J.col(3) = (k * (-(G * lg) * (e2f * ie1 * ie1) - (Z * lz) * (ie1 * ie1)) + 0.5f * r * s * lF)
                     .cast<double>()
                     .matrix();
      // e2 enters G's exponent and X, Y.
      J.col(4) = (k * ((G * lg) * ie1 - dGdg * (X * lx + Y * ly) * (ie2 * ie2))).cast<double>().matrix();
    }
    if (jacobians[1]) {  // d local / d t = -R^T
      Eigen::Map<RowMajorX> J(jacobians[1] + 3 * i0, m, 3);
      J = -DL.transpose().lazyProduct(f.Rt);
    }
    if (jacobians[2]) {  // d local / d angle = dR^T (p - t)
      Eigen::Map<RowMajorX> J(jacobians[2] + 3 * i0, m, 3);
      for (int a_k = 0; a_k < 3; ++a_k)
        J.col(a_k) = (DL.array() * f.dRt[a_k].lazyProduct(Q).array()).colwise().sum().transpose().matrix();
    }
  }

  Eigen::Matrix3Xd P_;
};

}  // namespace

ceres::CostFunction* newRadialResiduals(const std::vector<Point>& points) { return new RadialResiduals(points); }

void evaluateRadialResiduals(const PointList& points, const Superellipsoid& se,
                             Eigen::VectorXd* residuals, Eigen::MatrixXd* J) {
  const RadialResiduals cost(points);
  const double shape[5] = {se.a, se.b, se.c, se.e1, se.e2};
  const double* params[3] = {shape, se.t.data(), se.rpy.data()};
  const int n = static_cast<int>(points.size());
  Eigen::VectorXd r(n);
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  RowMajor j0(J ? n : 0, 5), j1(J ? n : 0, 3), j2(J ? n : 0, 3);
  double* jac[3] = {j0.data(), j1.data(), j2.data()};
  cost.Evaluate(params, r.data(), J ? jac : nullptr);
  if (residuals) *residuals = r;
  if (J) {
    J->resize(n, 11);
    *J << j0, j1, j2;
  }
}

Eigen::VectorXd radialDistances(const PointList& points, const Superellipsoid& shape) {
  Eigen::VectorXd r;
  evaluateRadialResiduals(points, shape, &r, nullptr);
  return r.cwiseAbs();
}

double rmsRadialDistance(const PointList& points, const Superellipsoid& shape) {
  if (points.empty()) return 0.0;
  Eigen::VectorXd r;
  evaluateRadialResiduals(points, shape, &r, nullptr);
  return std::sqrt(r.squaredNorm() / static_cast<double>(points.size()));
}

PointList evenlyStrided(const PointList& points, std::size_t at_most) {
  if (points.size() <= at_most) return points;
  PointList out;
  out.reserve(at_most);
  const double step = static_cast<double>(points.size()) / static_cast<double>(at_most);
  for (std::size_t i = 0; i < at_most; ++i) out.push_back(points[static_cast<std::size_t>(static_cast<double>(i) * step)]);
  return out;
}

}  // namespace fruit_shape_completion
