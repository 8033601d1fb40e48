#include <fruit_shape_completion/host/shape_estimator.h>
#include <fruit_shape_completion/host/update_worker.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <new>
#include <stdexcept>

namespace fruit_shape_completion {
namespace host {

ShapeEstimatorHost::ShapeEstimatorHost(Reporter report_error, Updates updates)
    : report_error_(std::move(report_error)), updates_(updates) {
  if (!report_error_) report_error_ = [](const std::string& msg) { std::cerr << msg << "\n"; };
}

ShapeEstimatorHost::~ShapeEstimatorHost() {
  std::vector<UpdateWorker*> workers;
  std::vector<ShapeEstimator*> estimators;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& w : workers_) workers.push_back(w.get());
    for (auto& e : estimators_) estimators.push_back(e.get());
  }
  for (auto* e : estimators) {
    try {
      e->cancelUpdate();
    } catch (...) {  // going away regardless
    }
  }
  for (auto* w : workers) w->stop();
}

void ShapeEstimatorHost::add(std::unique_ptr<ShapeEstimator> estimator) {
  if (!estimator) return;
  std::lock_guard<std::mutex> lock(mutex_);
  const std::size_t i = estimators_.size();
  estimators_.push_back(std::move(estimator));
  enabled_.push_back(1);
  last_error_.emplace_back();
  out_of_memory_.push_back(0);
  if (updates_ == Updates::kBackground)
    workers_.push_back(std::make_unique<UpdateWorker>([this, i] { guarded(i, [](ShapeEstimator& e) { e.update(); }); }));
}

std::size_t ShapeEstimatorHost::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return estimators_.size();
}

ShapeEstimator& ShapeEstimatorHost::estimator(std::size_t i) const {
  std::lock_guard<std::mutex> lock(mutex_);
  if (i >= estimators_.size()) throw std::out_of_range("no shape estimator " + std::to_string(i));
  return *estimators_[i];
}

bool ShapeEstimatorHost::enabled(std::size_t i) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return i < enabled_.size() && enabled_[i];
}

std::vector<std::string> ShapeEstimatorHost::errors() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return errors_;
}

std::string ShapeEstimatorHost::lastError(std::size_t i) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return i < last_error_.size() ? last_error_[i] : std::string();
}

std::size_t ShapeEstimatorHost::outOfMemoryDrops(std::size_t i) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return i < out_of_memory_.size() ? out_of_memory_[i] : 0;
}

void ShapeEstimatorHost::report(const std::string& msg) const {
  try {
    report_error_(msg);
  } catch (...) {  // a reporter that throws must not take the caller down either
  }
}

void ShapeEstimatorHost::dropOutOfMemory(std::size_t i) const {
  std::string msg;
  std::size_t n;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    n = ++out_of_memory_[i];
    msg = "shape estimator '" + estimators_[i]->name() + "': out of memory, call dropped (" + std::to_string(n) +
          " so far); what it had mapped is kept";
    last_error_[i] = msg;
  }
  // Every drop up to 10, then every 100th: a machine out of memory should not also flood the log.
  if (n <= 10 || n % 100 == 0) report(msg);
}

void ShapeEstimatorHost::fail(std::size_t i, const std::string& what, bool always) const {
  std::string msg;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!enabled_[i] && !always) return;  // another thread's call failed first and said so
    enabled_[i] = 0;
    msg = "shape estimator '" + estimators_[i]->name() + "' disabled: " + what;
    // The most recent only: an estimator that fails after every reset of a long evaluation
    // would otherwise grow the list without end.
    if (errors_.size() >= kKeptErrors) errors_.erase(errors_.begin());
    errors_.push_back(msg);
    last_error_[i] = msg;
    estimators_[i]->enabledChanged(false);
  }
  report(msg);
}

template <typename Call>
bool ShapeEstimatorHost::guarded(std::size_t i, Call&& call) const {
  ShapeEstimator* e;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (i >= estimators_.size() || !enabled_[i]) return false;
    e = estimators_[i].get();  // stable: estimators are never removed
  }
  try {
    call(*e);
    return true;
  } catch (const std::bad_alloc&) {
    dropOutOfMemory(i);
  } catch (const std::exception& ex) {
    fail(i, ex.what());
  } catch (...) {
    fail(i, "unknown exception");
  }
  return false;
}

void ShapeEstimatorHost::onView(const ViewData& view) {
  if (updates_ == Updates::kBackground) {
    insertView(view);
    requestUpdate();
    return;
  }
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0, n = size(); i < n; ++i)
    guarded(i, [&](ShapeEstimator& e) {
      e.insertView(view);
      e.update();
    });
  recordInsert(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
}

void ShapeEstimatorHost::recordInsert(double ms) {
  constexpr std::size_t kKept = 256;
  std::lock_guard<std::mutex> lock(mutex_);
  if (insert_ms_.size() < kKept) {
    insert_ms_.push_back(ms);
  } else {
    insert_ms_[insert_next_] = ms;
    insert_next_ = (insert_next_ + 1) % kKept;
  }
}

double ShapeEstimatorHost::insertLatencyMs(double q) const {
  std::vector<double> v;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    v = insert_ms_;
  }
  if (v.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

void ShapeEstimatorHost::requestUpdate() {
  if (updates_ == Updates::kInline) {
    update();
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  for (std::size_t i = 0; i < workers_.size(); ++i)
    if (enabled_[i]) workers_[i]->request();
}

bool ShapeEstimatorHost::waitForUpdates(double timeout) const {
  std::vector<UpdateWorker*> workers;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& w : workers_) workers.push_back(w.get());
  }
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
  for (auto* w : workers)
    if (!w->waitIdle(std::chrono::duration<double>(until - std::chrono::steady_clock::now()).count())) return false;
  return true;
}

ShapeEstimatorHost::UpdateStatus ShapeEstimatorHost::updateStatus(std::size_t i) const {
  UpdateWorker* w = nullptr;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (i < workers_.size()) w = workers_[i].get();
  }
  UpdateStatus out;
  if (!w) return out;
  const UpdateWorker::Status s = w->status();
  out.runs = s.runs;
  out.coalesced = s.coalesced;
  out.last_seconds = s.last_seconds;
  out.age_seconds = s.age_seconds;
  out.running = s.running;
  out.pending = s.pending;
  return out;
}

void ShapeEstimatorHost::insertView(const ViewData& view) {
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0, n = size(); i < n; ++i) guarded(i, [&](ShapeEstimator& e) { e.insertView(view); });
  recordInsert(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
}

void ShapeEstimatorHost::update() {
  for (std::size_t i = 0, n = size(); i < n; ++i) guarded(i, [&](ShapeEstimator& e) { e.update(); });
}

PointList ShapeEstimatorHost::extraTargets() const { return sharedViewTargets()->points; }

namespace {

// Appends an estimator's targets to `all`, skipping non-finite points and giving a zero direction
// or gain where the estimator gives none (or a non-finite one).
void appendChecked(const ShapeTargets& t, ShapeTargets* all) {
  const bool directed = t.directions.size() == t.points.size();
  const bool gained = t.gains.size() == t.points.size() && t.view_max_range > 0.0;
  if (gained && all->view_max_range <= 0.0) {  // the first estimator's cone: one camera
    all->view_cos_half_angle = t.view_cos_half_angle;
    all->view_max_range = t.view_max_range;
    // A bad value from another estimator turns the check off; a huge one would scan the map per view.
    all->view_clearance = t.view_clearance > 0.0 ? std::min(t.view_clearance, ShapeTargetParams::kMaxViewClearance) : 0.0;  // NaN: off
  }
  for (std::size_t k = 0; k < t.points.size(); ++k) {
    if (!t.points[k].allFinite()) continue;
    all->points.push_back(t.points[k]);
    const bool ok = directed && t.directions[k].allFinite();
    all->directions.push_back(ok ? t.directions[k] : Point::Zero());
    all->gains.push_back(gained && std::isfinite(t.gains[k]) ? t.gains[k] : 0.0);
  }
}

// True if appendChecked would hand over `t` unchanged: then it is passed on without a copy.
bool alreadyChecked(const ShapeTargets& t) {
  const std::size_t n = t.points.size();
  if (t.directions.size() != n) return false;
  const bool gained = t.view_max_range > 0.0;
  if (gained ? t.gains.size() != n : !t.gains.empty()) return false;
  if (!(t.view_clearance >= 0.0 && t.view_clearance <= ShapeTargetParams::kMaxViewClearance)) return false;
  for (std::size_t k = 0; k < n; ++k)
    if (!t.points[k].allFinite() || !t.directions[k].allFinite() || (gained && !std::isfinite(t.gains[k]))) return false;
  return true;
}

}  // namespace

ShapeTargets ShapeEstimatorHost::viewTargets() const { return *sharedViewTargets(); }

std::shared_ptr<const ShapeTargets> ShapeEstimatorHost::sharedViewTargets() const {
  std::vector<std::shared_ptr<const ShapeTargets>> parts;
  for (std::size_t i = 0, n = size(); i < n; ++i) {
    std::shared_ptr<const ShapeTargets> t;
    if (guarded(i, [&](ShapeEstimator& e) { t = e.sharedViewTargets(); }) && t) parts.push_back(std::move(t));
  }
  if (parts.size() == 1) {  // checked once per update of the one estimator, not per call
    std::lock_guard<std::mutex> lock(mutex_);
    if (parts[0] == targets_seen_) return targets_checked_;
  }
  std::shared_ptr<const ShapeTargets> checked;
  if (parts.size() == 1 && alreadyChecked(*parts[0])) {
    checked = parts[0];
  } else {
    auto all = std::make_shared<ShapeTargets>();
    for (const auto& t : parts) appendChecked(*t, all.get());
    if (all->view_max_range <= 0.0) all->gains.clear();
    checked = std::move(all);
  }
  if (parts.size() == 1) {
    std::lock_guard<std::mutex> lock(mutex_);
    targets_seen_ = parts[0];
    targets_checked_ = checked;
  }
  return checked;
}

std::shared_ptr<const std::vector<FruitEstimate>> ShapeEstimatorHost::sharedFruits(std::size_t i) const {
  std::shared_ptr<const std::vector<FruitEstimate>> f;
  guarded(i, [&](ShapeEstimator& e) { f = e.sharedFruits(); });
  return f ? f : std::make_shared<const std::vector<FruitEstimate>>();
}

std::vector<FruitEstimate> ShapeEstimatorHost::fruits(std::size_t i) const {
  std::vector<FruitEstimate> f;
  guarded(i, [&](ShapeEstimator& e) { f = e.fruits(); });  // f stays empty if it throws
  return f;
}

void ShapeEstimatorHost::reset() {
  for (std::size_t i = 0, n = size(); i < n; ++i) {
    ShapeEstimator& e = estimator(i);
    try {
      e.reset();
      {
        std::lock_guard<std::mutex> lock(mutex_);
        enabled_[i] = 1;
        // Counted since start or reset: a drop before it no longer colours the estimator's status.
        out_of_memory_[i] = 0;
        last_error_[i].clear();
        e.enabledChanged(true);
      }
    } catch (const std::exception& ex) {
      fail(i, std::string("reset failed: ") + ex.what(), true);
    } catch (...) {
      fail(i, "reset failed: unknown exception", true);
    }
  }
}

}  // namespace host
}  // namespace fruit_shape_completion
