#pragma once
// The superellipsoid shape estimator: TSDF fruit map -> surface -> clusters -> fits ->
// predicted unseen surface. Thread-safe: views may be inserted from one thread (sensor
// callbacks) while another (the planner) asks for fruits and targets and a third fits. Every
// view first goes through the fruit input stage (fruit_input_stage.h) as its source asks, in
// the caller's thread; its fruit points then wait in a short queue and update() integrates them
// into the map before it fits, in order. So a sensor callback waits neither for the map nor for
// a fit, unless kMaxPendingViews are waiting: then insertView takes the map (after the worker,
// if it holds it) and integrates the oldest itself; nothing is dropped. Queries read the last
// update's results and never wait for a fit. reset() cancels a running fit, whose results are
// then never stored: nothing fitted before a reset shows after it.
#include <fruit_shape_completion/fruit_input_stage.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/fruit_sightings.h>
#include <fruit_shape_completion/shape_targets.h>
#include <fruit_shape_completion/host/shape_estimator.h>
#include <fruit_shape_completion/tsdf_integrator.h>
#include <fruit_shape_completion/tsdf_surface.h>

#include <atomic>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace host {

struct SuperellipsoidEstimatorParams {
  FruitInputParams input;
  TsdfMapParams map;
  TsdfIntegratorParams integrator;
  SurfaceExtractionParams surface;
  PipelineParams pipeline;
  bool shape_targets = true;  // hand the predicted surface to the planner as extra targets
  ShapeTargetParams targets;   // which of it (shape_targets.h)
};

// The settings that may change while the estimator maps (cfg/Superellipsoid.cfg).
struct EstimatorLiveParams {
  FruitInputParams input;
  bool shape_targets = true;
  ShapeTargetParams targets;
  double refit_tolerance = 0.1;
  int max_fit_points = 300;
  double fit_function_tolerance = 1e-6, fit_stall_tolerance = 1e-3;
  double fit_noise_bias = 1.0;
  double fit_size_prior = 2e-6;
};

// The fruit input stage's totals, counted as views are inserted: views by source, and the points
// each step dropped.
struct InputTotals {
  std::size_t views = 0;
  std::size_t non_finite_points = 0;
  std::size_t camera_frames = 0, roi_views = 0, fruit_clouds = 0;
  std::size_t masked_points = 0, depth_edge_points = 0, veil_points = 0, outlier_points = 0;
};

// What the estimator has dropped since it started (or was reset), and its map's memory: the
// counters behind its warnings, for logs and diagnostics.
struct EstimatorStatus {
  std::size_t views_refused = 0;     // by the input stage or the map
  std::size_t views_without_fruit = 0;  // no fruit points left after the input stage: nothing to integrate
  std::size_t views_overtaken_by_reset = 0;  // still in insertView when a reset came: dropped, not mapped
  std::size_t points_skipped = 0;    // NaN/Inf, or outside the range limits
  std::size_t rays_outside = 0;      // partly outside the crop box or the map's range
  std::size_t rays_over_budget = 0;  // partly dropped at the memory budget
  std::size_t blocks = 0, max_blocks = 0;
  double memory_mb = 0.0;
  std::size_t fruits = 0;  // accepted at the last update
  std::size_t oversized_clusters = 0;  // at the last update: above cluster_max_size points, not fitted
  std::size_t undersized_points = 0;   // at the last update: in clusters below cluster_min_size, not fitted
  InputTotals input;  // including views still waiting for the map
};

class SuperellipsoidEstimator : public ShapeEstimator {
 public:
  // Views whose fruit points may wait for the next update(); beyond it insertView integrates.
  static constexpr std::size_t kMaxPendingViews = 8;
  explicit SuperellipsoidEstimator(const SuperellipsoidEstimatorParams& params = {});
  std::string name() const override { return "superellipsoid"; }
  void insertView(const ViewData& view) override;
  // insertView, returning the input stage's report of this view (its points not kept): with
  // several threads inserting, lastInput() may already be another thread's view.
  FruitInput insertViewReporting(const ViewData& view);
  void update() override;
  std::vector<FruitEstimate> fruits() const override;
  PointList extraTargets() const override;
  ShapeTargets viewTargets() const override;
  std::shared_ptr<const std::vector<FruitEstimate>> sharedFruits() const override;
  std::shared_ptr<const ShapeTargets> sharedViewTargets() const override;
  void reset() override;
  void cancelUpdate() override;  // for good: the estimator is going away

  // The fruit map as a file (TsdfMap::save/load); a failed load leaves the map unchanged. The
  // map is copied under the lock and written outside it, atomically (a temporary file renamed
  // over the target): views do not wait for the disk, and a failed save keeps the old file.
  // Both first remove the temporaries a killed save to the same path left behind, naming them
  // in *warning (empty if none). Views still waiting are integrated first (saved; replaced by
  // a loaded map, as if they had come before it).
  bool saveMap(const std::string& path, std::string* error, std::string* warning = nullptr);
  bool loadMap(const std::string& path, std::string* error, std::string* warning = nullptr);
  // The accepted fruits of the last update with the views that saw them (fruit_report.h), to a
  // .csv or .json file, atomically.
  bool exportFruits(const std::string& path, std::string* error, std::string* warning = nullptr,
                    std::size_t* written = nullptr) const;  // written: the fruits in the file
  std::map<int, FruitSightings> sightings() const;

  // The live settings, as last set.
  EstimatorLiveParams liveParams() const;
  // Checks them all first (std::invalid_argument naming the first bad value; nothing changes),
  // then applies the input stage's from the next view and the fit's and the targets' from the
  // next update; shape_targets off also empties the targets handed out from now on.
  void setLiveParams(const EstimatorLiveParams& live);

  // Snapshots for display and tests: every fruit of the last update, accepted ones first.
  std::vector<FruitEstimate> estimates() const;
  PointList surface() const;
  // The same surface as the map's blocks hold it: shares their points, nothing concatenated.
  SurfaceBlocks surfaceBlocks() const;
  // The last view integrated into the map (a view waits for the next update()); its error
  // is the input stage's if that refused the view.
  IntegrationReport lastIntegration() const;
  // The integrated views the map refused or cut (error or warning set) since the last call,
  // oldest first, at most 2 * kMaxPendingViews: what a host logs after an update. (The input
  // stage's refusals are in insertViewReporting's report.)
  std::vector<IntegrationReport> takeIntegrationProblems();
  // The input stage's report of the last view inserted by any thread (its points not kept).
  FruitInput lastInput() const;
  PipelineStats lastPipelineStats() const;
  // The input stage's totals include waiting views; the map's counters (refused, skipped,
  // rays, blocks) only integrated ones.
  EstimatorStatus status() const;
  std::size_t pendingViews() const;
  double lastSurfaceSeconds() const;  // surface extraction of the last update

 private:
  // The start values; shape_targets and targets change under fit_mutex_ (the live input stage
  // is input_stage_, the live pipeline settings pipeline_'s).
  SuperellipsoidEstimatorParams params_;
  const PipelineParams start_pipeline_;
  PipelineParams pipelineWith(const EstimatorLiveParams& live) const;
  // Makes a running update return early and store nothing (reset, load), and holds fit_mutex_
  // until the caller has replaced what the update would have read.
  std::unique_lock<std::mutex> cancelRunningFit();
  // New target settings on an unchanged map: the last fits' targets are selected again (under
  // fit_mutex_), so that a change reaches the planner without waiting for a view.
  void selectTargetsAgain();
  // Swapped whole by setLiveParams; a view runs the stage it took, outside the locks.
  std::shared_ptr<const FruitInputStage> input_stage_;
  // Guards input_stage_, live_ and live_pending_; held briefly, never while taking another lock.
  mutable std::mutex live_mutex_;
  EstimatorLiveParams live_;
  bool live_pending_ = false;  // live_ not yet applied to the fit (params_, pipeline_)
  std::atomic<bool> targets_on_{true};
  // Lock order: fit_mutex_, then live_mutex_ or map_mutex_, then pending_mutex_, then
  // results_mutex_, then sightings_mutex_.
  std::mutex fit_mutex_;  // one update at a time; guards pipeline_
  std::atomic<bool> cancel_{false};  // a running update returns early and stores nothing
  // Resets so far: a view that was already in insertView when a reset came belongs to the map
  // that is gone (the planner cleared its tree before the reset) and is not mapped.
  std::atomic<std::uint64_t> resets_{0};
  std::atomic<std::size_t> views_overtaken_by_reset_{0};
  std::atomic<bool> stopping_{false};   // cancelUpdate(): cancel_ stays set
  std::atomic<int> resets_waiting_{0};  // resets that set cancel_ and wait for the fit
  FruitShapePipeline pipeline_;
  mutable std::mutex map_mutex_;  // guards the members below up to pending_mutex_
  TsdfMap map_;
  IncrementalSurfaceExtractor surface_extractor_;
  TsdfIntegrator integrator_;
  IntegrationReport last_;
  std::vector<IntegrationReport> problems_;  // not yet taken
  EstimatorStatus totals_;  // the map's counters
  bool dirty_ = false;
  // A view's fruit points as the input stage left them, waiting for the map.
  struct PendingView {
    PointList fruit;
    Eigen::Isometry3d sensor_pose;
    std::string refused;  // the input stage's error: counted, not integrated
  };
  // Integrates the oldest waiting views (all by default) in order; map_mutex_ held.
  void integratePending(std::size_t max_views = std::numeric_limits<std::size_t>::max());
  mutable std::mutex pending_mutex_;  // guards the members below up to results_mutex_
  std::vector<PendingView> pending_;
  FruitInput last_input_;
  InputTotals input_totals_;
  mutable std::mutex results_mutex_;  // guards the last update's results below
  // Swapped whole by each update, never changed in place: queries share them.
  std::shared_ptr<const std::vector<FruitEstimate>> accepted_ = std::make_shared<const std::vector<FruitEstimate>>();
  std::vector<FruitEstimate> rejected_;
  SurfaceBlocks surface_;
  std::shared_ptr<const ShapeTargets> targets_ = std::make_shared<const ShapeTargets>();
  PipelineStats stats_;
  double surface_seconds_ = 0.0;
  mutable std::mutex sightings_mutex_;  // guards sightings_; always taken last
  FruitSightingLog sightings_;
};

}  // namespace host
}  // namespace fruit_shape_completion
