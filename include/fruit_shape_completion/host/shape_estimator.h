#pragma once
// The seam between the viewpoint planner and fruit shape estimators (the pluginlib base class
// of the ROS layer wraps exactly this). After each inserted view the host hands every
// estimator the view and lets it update; before sampling views it collects the estimators'
// extra ROI targets (e.g. the predicted, unseen fruit surface).
#include <fruit_shape_completion/fruit_estimate.h>
#include <fruit_shape_completion/shape_targets.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace fruit_shape_completion {

struct OrganizedFrame;  // fruit_input_stage.h

namespace host {

class UpdateWorker;  // update_worker.h

// What a view's points are, and so which steps of the fruit input stage (fruit_input_stage.h)
// they still need.
enum class ViewSource {
  kFruitPoints,  // fruit_cloud is ready for the map: integrated as it is
  kFruitCloud,   // an external detector's full-resolution fruit points: outlier removal first
  kRoiCloud,     // pointcloud_roi's 1 cm view: full_cloud all of it, fruit_cloud its ROI points
  kCameraFrame,  // camera_frame (and fruit_mask, if a detector made one): the whole stage
};

struct ViewData {
  const PointList& fruit_cloud;   // fruit points, map frame
  const PointList& full_cloud;    // all points, map frame
  Eigen::Isometry3d sensor_pose;  // sensor -> map, optical axis +z
  double time = 0.0;              // [s] the view's stamp (ROS time, or time since the episode start)
  ViewSource source = ViewSource::kFruitPoints;
  const OrganizedFrame* camera_frame = nullptr;           // kCameraFrame, in the sensor frame
  const std::vector<std::uint8_t>* fruit_mask = nullptr;  // kCameraFrame: replaces the red test
};

// Implementations must be thread-safe: the upstream planner inserts views from its spinner
// threads while its planning thread asks for targets and fruits, and resets from a service.
class ShapeEstimator {
 public:
  virtual ~ShapeEstimator() = default;
  virtual std::string name() const = 0;
  virtual void insertView(const ViewData& view) = 0;
  virtual void update() = 0;
  // The accepted fruits (center() and volume are what the planner evaluates).
  virtual std::vector<FruitEstimate> fruits() const = 0;
  virtual PointList extraTargets() const = 0;
  // The same targets, with the direction to view each from where the estimator knows it; the
  // default gives none (any side).
  virtual ShapeTargets viewTargets() const {
    ShapeTargets t;
    t.points = extraTargets();
    return t;
  }
  // The same results shared, never changed once handed out: what a planner asks for every round
  // without copying every fruit's points. The defaults copy once per call.
  virtual std::shared_ptr<const std::vector<FruitEstimate>> sharedFruits() const {
    return std::make_shared<const std::vector<FruitEstimate>>(fruits());
  }
  virtual std::shared_ptr<const ShapeTargets> sharedViewTargets() const {
    return std::make_shared<const ShapeTargets>(viewTargets());
  }
  virtual void reset() = 0;
  // Asks a running update() to return soon without publishing its results: the estimator is
  // going away. May be called from any thread; the default does nothing.
  virtual void cancelUpdate() {}
  // The host has disabled the estimator (false: one of its calls threw) or enabled it again (true:
  // a reset succeeded). An estimator that also maps or publishes on its own (its own
  // subscriptions, say) stops and resumes there too, so that it does not go on publishing what
  // its status calls disabled. Called under the host's lock, so that a failure and a reset in two
  // threads leave both sides agreeing: it must only record the state (no call into the host, no
  // waiting), and must not throw. The default does nothing.
  virtual void enabledChanged(bool /*enabled*/) noexcept {}
};

// Owns the estimators; an estimator that throws is disabled with a message, never taking the
// planner down. Running out of memory is different: the call is dropped, counted and reported,
// and the estimator stays enabled with what it had (the next, smaller view may fit). Every
// method may be called from several threads at once (add() before the first view). The
// estimators are called outside the host's lock: a long fit in one thread does not block
// queries of the host's state in another.
//
// With background updates (what a planner's process wants), each estimator gets a worker
// thread: onView() returns once the estimators have taken the view (the superellipsoid
// estimator cuts out its fruit points and leaves the map to its worker), the fit runs beside
// the planner on the newest map, and views that arrive meanwhile coalesce into the next fit.
class ShapeEstimatorHost {
 public:
  // Where the host reports a disabled estimator (default: std::cerr); the ROS layer passes
  // rosconsole.
  using Reporter = std::function<void(const std::string&)>;
  enum class Updates { kInline, kBackground };
  explicit ShapeEstimatorHost(Reporter report_error = nullptr, Updates updates = Updates::kInline);
  // Stops the workers (a running fit is cancelled) before the estimators go.
  ~ShapeEstimatorHost();
  ShapeEstimatorHost(const ShapeEstimatorHost&) = delete;
  ShapeEstimatorHost& operator=(const ShapeEstimatorHost&) = delete;

  void add(std::unique_ptr<ShapeEstimator> estimator);
  // Insert into every enabled estimator, then update: inline, or requested from the workers.
  void onView(const ViewData& view);
  // The two halves, for a host that updates on a timer instead of after every view. update()
  // runs in the caller's thread whatever the mode; requestUpdate() hands it to the workers
  // (inline mode: runs it).
  void insertView(const ViewData& view);
  void update();
  void requestUpdate();
  // Background mode: until no update is pending or running, or `timeout` seconds.
  bool waitForUpdates(double timeout) const;
  struct UpdateStatus {
    std::size_t runs = 0, coalesced = 0;
    double last_seconds = 0.0, age_seconds = -1.0;  // the last finished update; age < 0: none
    bool running = false, pending = false;  // pending: requested, not yet started
  };
  UpdateStatus updateStatus(std::size_t i) const;  // background mode; zeros inline
  // How long the last (up to 256) insertView/onView calls held their caller [ms]: what a
  // planner waits for. Quantile q in [0, 1]; 0 if there was none.
  double insertLatencyMs(double q) const;
  PointList extraTargets() const;
  // All estimators' targets with their directions (zero where an estimator gives none).
  ShapeTargets viewTargets() const;
  // The same, shared: one estimator's results are passed on as they are once checked (per
  // update, not per call); several estimators' are joined.
  std::shared_ptr<const ShapeTargets> sharedViewTargets() const;
  // Fruits of estimator i, shared (empty if it throws).
  std::shared_ptr<const std::vector<FruitEstimate>> sharedFruits(std::size_t i) const;
  // Fruits of estimator i; empty (and the estimator disabled) if it throws.
  std::vector<FruitEstimate> fruits(std::size_t i) const;
  std::size_t size() const;
  ShapeEstimator& estimator(std::size_t i) const;  // i < size()
  bool enabled(std::size_t i) const;
  // The messages of the estimators disabled so far (the most recent kKeptErrors).
  std::vector<std::string> errors() const;
  static constexpr std::size_t kKeptErrors = 100;
  // The last error of estimator i ("" if none), and how many of its calls ran out of memory;
  // both since start or the last reset that re-enabled it.
  std::string lastError(std::size_t i) const;
  std::size_t outOfMemoryDrops(std::size_t i) const;
  // Resets every estimator and re-enables those whose reset succeeds.
  void reset();

 private:
  // Disables estimator i and records and reports `what`; unless `always`, only if it was still
  // enabled (two threads failing at once give one message).
  void fail(std::size_t i, const std::string& what, bool always = false) const;
  // Counts and reports a call of estimator i that ran out of memory.
  void dropOutOfMemory(std::size_t i) const;
  void report(const std::string& msg) const;
  // Runs call(estimator i); if it throws, disables the estimator with the message (or, out of
  // memory, drops the call) and returns false.
  template <typename Call>
  bool guarded(std::size_t i, Call&& call) const;

  Reporter report_error_;
  const Updates updates_;
  mutable std::mutex mutex_;  // guards the members below
  std::vector<std::unique_ptr<UpdateWorker>> workers_;  // background mode: one per estimator
  std::vector<double> insert_ms_;  // ring of the last calls' durations
  std::size_t insert_next_ = 0;
  void recordInsert(double ms);
  std::vector<std::unique_ptr<ShapeEstimator>> estimators_;  // only grows
  mutable std::vector<char> enabled_;
  mutable std::vector<std::string> errors_;
  mutable std::vector<std::string> last_error_;      // per estimator
  mutable std::vector<std::size_t> out_of_memory_;  // per estimator
  // The last shared targets an estimator handed out, and what was given for them (the same
  // snapshot when nothing needed fixing).
  mutable std::shared_ptr<const ShapeTargets> targets_seen_, targets_checked_;
};

}  // namespace host
}  // namespace fruit_shape_completion
