#include <fruit_shape_completion/superellipsoid_fit.h>

#include <ceres/ceres.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace fruit_shape_completion {

namespace {

// sqrt(N alpha) (t - w)
struct CenterPrior {
  CenterPrior(const Eigen::Vector3d& w, double weight) : w_(w), s_(std::sqrt(weight)) {}
  template <typename T>
  bool operator()(const T* t, T* residual) const {
    for (int k = 0; k < 3; ++k) residual[k] = T(s_) * (t[k] - T(w_[k]));
    return true;
  }
  Eigen::Vector3d w_;
  double s_;
};

// sqrt(N gamma) (a - b, b - c, c - a)
struct AxisSimilarityPrior {
  explicit AxisSimilarityPrior(double weight) : s_(std::sqrt(weight)) {}
  template <typename T>
  bool operator()(const T* shape, T* residual) const {
    residual[0] = T(s_) * (shape[0] - shape[1]);
    residual[1] = T(s_) * (shape[1] - shape[2]);
    residual[2] = T(s_) * (shape[2] - shape[0]);
    return true;
  }
  double s_;
};

// sqrt(N kappa (1 + log(abc / m^3))), m the lower axis bound: the cost N kappa log(abc) plus a
// constant that keeps the root's argument at least N kappa within the bounds (a root of zero has
// no derivative). The stopping rules' relative tolerances read that constant as cost too (about
// the data's own at a 2-3 mm RMS): the defaults were measured with it.
struct SizePrior {
  SizePrior(double weight, double min_axis) : s_(weight), m_(min_axis) {}
  template <typename T>
  bool operator()(const T* shape, T* residual) const {
    using std::log;
    using std::sqrt;
    const T l = T(1.0) + log(shape[0] / T(m_)) + log(shape[1] / T(m_)) + log(shape[2] / T(m_));
    residual[0] = sqrt(T(s_) * l);
    return true;
  }
  double s_, m_;
};

double wrapAngle(double a) { return std::atan2(std::sin(a), std::cos(a)); }

// The residuals' variance as their median absolute deviation reads it (1.4826 MAD, squared):
// the noise that moves points along the surface. A fused map's points that a view's depth offset
// left a centimetre inside a fruit widen the RMS, not the bulk of the residuals.
double robustResidualVariance(const Eigen::VectorXd& r) {
  std::vector<double> v(r.data(), r.data() + r.size());
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  const double median = *mid;
  for (double& x : v) x = std::abs(x - median);
  std::nth_element(v.begin(), mid, v.end());
  const double sigma = 1.4826 * *mid;
  return sigma * sigma;
}

// Shrinks `shape` about its centre, and returns the factor, by weight x sigma^2 / R
// (FitParams::noise_bias), sigma^2 the robust variance of its `residuals` (never above the
// RMS^2), sigma at most kMaxNoise: a 4 mm map of an RGB-D camera's depth leaves
// about that much noise on a fruit's surface, and residuals beyond it are misfit (lobes, a
// fragment of a fruit, touching fruits), which moves no point outward. Never below half (only
// reachable with a min_axis far below any fruit's size).
constexpr double kMaxNoise = 0.003;
double removeNoiseBias(const Eigen::VectorXd& residuals, double rms, double weight, Superellipsoid* shape) {
  const double r = std::cbrt(shape->a * shape->b * shape->c);
  if (!(weight > 0.0) || !(r > 0.0)) return 1.0;
  const double variance = std::min({kMaxNoise * kMaxNoise, robustResidualVariance(residuals), rms * rms});
  const double scale = std::max(0.5, 1.0 - weight * variance / (r * r));
  shape->a *= scale;
  shape->b *= scale;
  shape->c *= scale;
  return scale;
}

}  // namespace

void FitParams::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument(what); };
  if (!(alpha >= 0.0) || !std::isfinite(alpha)) fail("alpha must be a finite value >= 0");
  if (!(gamma >= 0.0) || !std::isfinite(gamma)) fail("gamma must be a finite value >= 0");
  if (!(min_axis > 0.0) || !(max_axis > min_axis) || !std::isfinite(max_axis))
    fail("axis bounds must satisfy 0 < min_axis < max_axis");
  if (!(min_e > 0.0) || !(max_e > min_e) || !(max_e <= 2.0))
    fail("exponent bounds must satisfy 0 < min_e < max_e <= 2");
  if (!(initial_axis >= min_axis && initial_axis <= max_axis))
    fail("initial_axis must lie within the axis bounds");
  if (!(initial_e >= min_e && initial_e <= max_e))
    fail("initial_e must lie within the exponent bounds");
  if (max_iterations < 1) fail("max_iterations must be >= 1");
  if (max_points != 0 && max_points < 11) fail("max_points (max_fit_points) must be 0 (all) or >= 11");
  if (!(function_tolerance > 0.0 && function_tolerance < 1.0)) fail("function_tolerance must be in (0, 1)");
  if (!(stall_tolerance >= 0.0 && stall_tolerance < 1.0)) fail("stall_tolerance must be in [0, 1)");
  if (!(max_rms > 0.0)) fail("max_rms must be > 0");
  if (!(noise_bias >= 0.0 && noise_bias <= 3.0)) fail("noise_bias must be in [0, 3]");
  if (!(size_prior >= 0.0 && size_prior <= 1e-4)) fail("size_prior must be in [0, 1e-4]");
}

namespace {

constexpr size_t kStartSubsample = 80;  // points per competing start
constexpr int kStartRace = 15;          // iterations each start runs before the lowest goes on

struct Solution {
  double shape[5], t[3], rpy[3];
  double cost = 0.0;
  bool converged = false;
  int iterations = 0;
  std::string message;
};

// The bounds of shape coordinate k (a, b, c, e1, e2).
double lowerBound(const FitParams& params, int k) { return k < 3 ? params.min_axis : params.min_e; }
double upperBound(const FitParams& params, int k) { return k < 3 ? params.max_axis : params.max_e; }

// The shape's box as a manifold: a step is clamped into the bounds, and `held` coordinates do
// not move. Ceres' own parameter bounds do the same clamping, but they also make every LM
// iteration run a projected line search that evaluates the Jacobian once more (Ceres calls
// that search "not terribly effective", issue 187); this keeps the problem unconstrained.
class ShapeBox : public ceres::Manifold {
 public:
  ShapeBox(const FitParams& params, const std::vector<int>& held) {
    for (int k = 0; k < 5; ++k) {
      lower_[k] = lowerBound(params, k);
      upper_[k] = upperBound(params, k);
      if (std::find(held.begin(), held.end(), k) == held.end()) free_.push_back(k);
    }
  }
  int AmbientSize() const override { return 5; }
  int TangentSize() const override { return static_cast<int>(free_.size()); }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    std::copy(x, x + 5, x_plus_delta);
    for (std::size_t i = 0; i < free_.size(); ++i) {
      const int k = free_[i];
      x_plus_delta[k] = std::min(upper_[k], std::max(lower_[k], x[k] + delta[i]));
    }
    return true;
  }
  bool PlusJacobian(const double* /*x*/, double* jacobian) const override {  // 5 x tangent, row major
    std::fill(jacobian, jacobian + 5 * free_.size(), 0.0);
    for (std::size_t i = 0; i < free_.size(); ++i) jacobian[free_[i] * free_.size() + i] = 1.0;
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    for (std::size_t i = 0; i < free_.size(); ++i) y_minus_x[i] = y[free_[i]] - x[free_[i]];
    return true;
  }
  bool MinusJacobian(const double* /*x*/, double* jacobian) const override {  // tangent x 5
    std::fill(jacobian, jacobian + 5 * free_.size(), 0.0);
    for (std::size_t i = 0; i < free_.size(); ++i) jacobian[i * 5 + free_[i]] = 1.0;
    return true;
  }

 private:
  double lower_[5], upper_[5];
  std::vector<int> free_;
};

// Once an exponent or an axis presses against its bound, the steps of the other parameters,
// computed as if it could move on, are mostly wasted and LM crawls for tens of iterations. So a
// solve that has not converged after a few iterations holds the shape coordinates that sit on a
// bound (an active set) and goes on; at the end it lets them go again only if the cost would
// fall by moving one back inside.
constexpr int kProbeIterations = 8;

std::vector<int> coordinatesOnBounds(const double shape[5], const FitParams& params) {
  std::vector<int> on;
  for (int k = 0; k < 5; ++k)
    if (shape[k] <= lowerBound(params, k) || shape[k] >= upperBound(params, k)) on.push_back(k);
  return on;
}

// Ends a solve whose cost fell by less than `tolerance` (relative) over the last kWindow
// accepted steps (FitParams::stall_tolerance). A per-step tolerance that loose would also stop
// on a single small step early on.
class StallStop : public ceres::IterationCallback {
 public:
  explicit StallStop(double tolerance) : tolerance_(tolerance) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    if (!(tolerance_ > 0.0) || !summary.step_is_successful) return ceres::SOLVER_CONTINUE;
    costs_.push_back(summary.cost);
    if (costs_.size() <= kWindow) return ceres::SOLVER_CONTINUE;
    const double before = costs_[costs_.size() - 1 - kWindow];
    return before - summary.cost < tolerance_ * summary.cost ? ceres::SOLVER_TERMINATE_SUCCESSFULLY
                                                             : ceres::SOLVER_CONTINUE;
  }
  void reset() { costs_.clear(); }

 private:
  static constexpr std::size_t kWindow = 5;
  double tolerance_;
  std::vector<double> costs_;
};

// One Levenberg-Marquardt run from `sol`'s parameters, which it overwrites.
void solve(const std::vector<Point>& points, const Eigen::Vector3d& center_prior,
           const FitParams& params, Solution& sol) {
  ceres::Problem problem;
  const double n = static_cast<double>(points.size());
  problem.AddResidualBlock(newRadialResiduals(points), nullptr, sol.shape, sol.t, sol.rpy);
  if (params.alpha > 0.0)
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CenterPrior, 3, 3>(
                                 new CenterPrior(center_prior, n * params.alpha)),
                             nullptr, sol.t);
  if (params.size_prior > 0.0)
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<SizePrior, 1, 5>(
                                 new SizePrior(n * params.size_prior, params.min_axis)),
                             nullptr, sol.shape);
  if (params.gamma > 0.0)
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<AxisSimilarityPrior, 3, 5>(
                                 new AxisSimilarityPrior(n * params.gamma)),
                             nullptr, sol.shape);
  ceres::Solver::Options options;
  options.minimizer_type = ceres::TRUST_REGION;
  options.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  options.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  options.function_tolerance = params.function_tolerance;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  StallStop stall(params.stall_tolerance);
  options.callbacks.push_back(&stall);
  int budget = params.max_iterations;
  sol.iterations = 0;
  auto run = [&](int max_iterations) {
    options.max_num_iterations = std::max(1, max_iterations);
    ceres::Solver::Summary summary;
    stall.reset();
    ceres::Solve(options, &problem, &summary);
    const int done = std::max(0, static_cast<int>(summary.iterations.size()) - 1);
    sol.iterations += done;
    budget -= std::max(1, done);
    sol.cost = summary.final_cost;
    sol.converged = summary.termination_type == ceres::CONVERGENCE || summary.termination_type == ceres::USER_SUCCESS;
    sol.message = summary.message;
  };
  // Holds `held` (shape coordinates) constant; none: all free again.
  auto hold = [&](const std::vector<int>& held) {
    if (held.size() == 5) {
      problem.SetParameterBlockConstant(sol.shape);
      return;
    }
    problem.SetParameterBlockVariable(sol.shape);
    problem.SetManifold(sol.shape, new ShapeBox(params, held));
  };

  hold({});
  run(std::min(budget, kProbeIterations));
  const std::vector<int> held = coordinatesOnBounds(sol.shape, params);
  if (sol.converged || budget <= 0 || held.empty()) {
    if (!sol.converged && budget > 0) run(budget);
    return;
  }
  hold(held);
  run(budget);
  if (!sol.converged) return;
  // Let the held coordinates go if the cost falls by moving one of them back inside its box.
  hold({});
  std::vector<double> gradient;
  double cost = 0.0;
  ceres::Problem::EvaluateOptions eval;
  eval.parameter_blocks = {sol.shape, sol.t, sol.rpy};
  problem.Evaluate(eval, &cost, nullptr, &gradient, nullptr);
  bool inward = false;
  for (int k : held)
    inward = inward || (sol.shape[k] >= upperBound(params, k) ? gradient[k] > 0.0 : gradient[k] < 0.0);
  if (inward && budget > 0) run(budget);
}

}  // namespace

FitResult fitSuperellipsoid(const PointList& points, const Eigen::Vector3d& center_prior,
                            const FitParams& params, const Superellipsoid* initial) {
  const auto start = std::chrono::steady_clock::now();
  FitResult result;
  auto finish = [&](const std::string& reason) {
    result.reason = reason;
    result.accepted = reason.empty();
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
  };
  if (!center_prior.allFinite()) return finish("centre prior is not finite");
  std::vector<Point> finite;
  finite.reserve(points.size());
  for (const auto& p : points)
    if (p.allFinite()) finite.push_back(p);
  const int n = static_cast<int>(finite.size());
  if (n < 11) return finish("fewer finite points than parameters");

  // Starting points: a previous fit (clamped into the bounds), or the paper's start
  // (a = b = c = initial_axis, e1 = e2 = initial_e, t = w, rpy = 0) plus, with
  // extra_starts, the same with the shape's z axis along world x and along world y, since
  // LM rarely swaps which axis carries e1.
  std::vector<Solution> starts;
  if (initial != nullptr && initial->isFinite()) {
    Solution s;
    const double v[5] = {initial->a, initial->b, initial->c, initial->e1, initial->e2};
    for (int k = 0; k < 5; ++k)
      s.shape[k] = std::min(upperBound(params, k), std::max(lowerBound(params, k), v[k]));
    for (int k = 0; k < 3; ++k) {
      s.t[k] = initial->t[k];
      s.rpy[k] = initial->rpy[k];
    }
    starts.push_back(s);
  } else {
    const double rotations[3][3] = {{0, 0, 0}, {0, M_PI / 2, 0}, {M_PI / 2, 0, 0}};
    const int count = params.extra_starts ? 3 : 1;
    for (int r = 0; r < count; ++r) {
      Solution s;
      s.shape[0] = s.shape[1] = s.shape[2] = params.initial_axis;
      s.shape[3] = s.shape[4] = params.initial_e;
      for (int k = 0; k < 3; ++k) {
        s.t[k] = center_prior[k];
        s.rpy[k] = rotations[r][k];
      }
      starts.push_back(s);
    }
  }
  // Several starts compete on an even subsample of the points for kStartRace iterations each;
  // the one lowest then goes on to converge there, and only it is refined on all of them.
  // Starts that reach different minima part within the race; the rest of their descent would
  // only be paid to be thrown away.
  Solution* best = &starts.front();
  if (starts.size() > 1) {
    std::vector<Point> subsample;
    const size_t step = std::max<size_t>(1, finite.size() / kStartSubsample);
    for (size_t i = 0; i < finite.size(); i += step) subsample.push_back(finite[i]);
    FitParams race = params;
    race.max_iterations = std::min(params.max_iterations, kStartRace);
    for (auto& s : starts) {
      solve(subsample, center_prior, race, s);
      result.iterations += s.iterations;
      if (std::isfinite(s.cost) && (!std::isfinite(best->cost) || s.cost < best->cost)) best = &s;
    }
    if (!best->converged && params.max_iterations > race.max_iterations) {
      race.max_iterations = params.max_iterations - race.max_iterations;
      solve(subsample, center_prior, race, *best);
      result.iterations += best->iterations;
    }
  }
  Solution final_solution = *best;
  if (params.max_points > 0 && finite.size() > static_cast<size_t>(params.max_points)) {
    solve(evenlyStrided(finite, static_cast<size_t>(params.max_points)), center_prior, params, final_solution);
  } else {
    solve(finite, center_prior, params, final_solution);
  }
  result.iterations += final_solution.iterations;
  best = &final_solution;

  Superellipsoid& se = result.shape;
  se.a = best->shape[0];
  se.b = best->shape[1];
  se.c = best->shape[2];
  se.e1 = best->shape[3];
  se.e2 = best->shape[4];
  se.t = Eigen::Vector3d(best->t[0], best->t[1], best->t[2]);
  se.rpy = Eigen::Vector3d(wrapAngle(best->rpy[0]), wrapAngle(best->rpy[1]), wrapAngle(best->rpy[2]));
  result.converged = best->converged;

  // One evaluation of the residuals for the RMS (rmsRadialDistance's) and the noise bias.
  Eigen::VectorXd residuals;
  evaluateRadialResiduals(finite, se, &residuals, nullptr);
  result.rms = std::sqrt(residuals.squaredNorm() / static_cast<double>(finite.size()));

  if (!se.isFinite() || !std::isfinite(result.rms)) return finish("fit produced non-finite values");
  result.noise_scale = removeNoiseBias(residuals, result.rms, params.noise_bias, &se);
  if (!result.converged) {
    std::ostringstream os;
    os << "not converged after " << best->iterations << " iterations (" << best->message << ")";
    return finish(os.str());
  }
  if (result.rms > params.max_rms) {
    std::ostringstream os;
    os << "implausible: RMS residual " << result.rms * 1000.0 << " mm exceeds "
       << params.max_rms * 1000.0 << " mm";
    return finish(os.str());
  }
  return finish("");
}

}  // namespace fruit_shape_completion
