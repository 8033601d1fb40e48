#include <fruit_shape_completion/host/superellipsoid_estimator.h>

#include <fruit_shape_completion/atomic_file.h>
#include <fruit_shape_completion/fruit_report.h>

#include <algorithm>
#include <chrono>
#include <iterator>

namespace fruit_shape_completion {
namespace host {

SuperellipsoidEstimator::SuperellipsoidEstimator(const SuperellipsoidEstimatorParams& params)
    : params_(params), start_pipeline_(params.pipeline), input_stage_(std::make_shared<const FruitInputStage>(params.input)), pipeline_(params.pipeline),
      map_(params.map), surface_extractor_(params.surface), integrator_(params.integrator) {
  params_.targets.validate();
  live_.input = params.input;
  live_.shape_targets = params.shape_targets;
  live_.targets = params.targets;
  live_.refit_tolerance = params.pipeline.refit_tolerance;
  live_.max_fit_points = params.pipeline.fit.max_points;
  live_.fit_function_tolerance = params.pipeline.fit.function_tolerance;
  live_.fit_stall_tolerance = params.pipeline.fit.stall_tolerance;
  live_.fit_noise_bias = params.pipeline.fit.noise_bias;
  live_.fit_size_prior = params.pipeline.fit.size_prior;
  targets_on_ = params.shape_targets;
}

PipelineParams SuperellipsoidEstimator::pipelineWith(const EstimatorLiveParams& live) const {
  PipelineParams pipeline = start_pipeline_;  // only the live fields differ from the start values
  pipeline.refit_tolerance = live.refit_tolerance;
  pipeline.fit.max_points = live.max_fit_points;
  pipeline.fit.function_tolerance = live.fit_function_tolerance;
  pipeline.fit.stall_tolerance = live.fit_stall_tolerance;
  pipeline.fit.noise_bias = live.fit_noise_bias;
  pipeline.fit.size_prior = live.fit_size_prior;
  return pipeline;
}

namespace {

// Whether the live fields pipelineWith sets (its list) differ: a change of target or input
// settings alone must not make the next update cluster the whole map again.
bool liveFieldsDiffer(const PipelineParams& a, const PipelineParams& b) {
  return a.refit_tolerance != b.refit_tolerance || a.fit.max_points != b.fit.max_points ||
         a.fit.function_tolerance != b.fit.function_tolerance || a.fit.stall_tolerance != b.fit.stall_tolerance ||
         a.fit.noise_bias != b.fit.noise_bias || a.fit.size_prior != b.fit.size_prior;
}

}  // namespace

EstimatorLiveParams SuperellipsoidEstimator::liveParams() const {
  std::lock_guard<std::mutex> lock(live_mutex_);
  return live_;
}

void SuperellipsoidEstimator::setLiveParams(const EstimatorLiveParams& live) {
  live.input.validate();
  live.targets.validate();
  pipelineWith(live).validate();
  auto stage = std::make_shared<const FruitInputStage>(live.input);
  std::lock_guard<std::mutex> lock(live_mutex_);
  input_stage_ = std::move(stage);
  live_ = live;
  live_pending_ = true;
  targets_on_ = live.shape_targets;
}

namespace {

FruitInput runInputStage(const FruitInputStage& stage, const ViewData& view) {
  switch (view.source) {
    case ViewSource::kCameraFrame:
      if (!view.camera_frame) {
        FruitInput refused;
        refused.error = "a camera-frame view without a frame";
        return refused;
      }
      return stage.processFrame(*view.camera_frame, view.sensor_pose, view.fruit_mask);
    case ViewSource::kRoiCloud:
      return stage.processRoiCloud(view.full_cloud, view.fruit_cloud, view.sensor_pose.translation());
    case ViewSource::kFruitCloud:
      return stage.processFruitCloud(view.fruit_cloud);
    case ViewSource::kFruitPoints:
      break;
  }
  FruitInput as_is;
  as_is.fruit = view.fruit_cloud;
  as_is.points = view.fruit_cloud.size();
  return as_is;
}

}  // namespace

void SuperellipsoidEstimator::insertView(const ViewData& view) { insertViewReporting(view); }

FruitInput SuperellipsoidEstimator::insertViewReporting(const ViewData& view) {
  const std::uint64_t resets_before = resets_.load();
  // The stage reads only the view and its own constant parameters: no lock while it runs.
  std::shared_ptr<const FruitInputStage> stage;
  {
    std::lock_guard<std::mutex> lock(live_mutex_);
    stage = input_stage_;
  }
  FruitInput input = runInputStage(*stage, view);
  if (input.ok()) {
    std::lock_guard<std::mutex> lock(sightings_mutex_);
    if (resets_.load() == resets_before) sightings_.addView(view.time, input.fruit, view.sensor_pose);
  }
  input.full.clear();  // the report keeps its counts, not its points
  input.mask.clear();
  bool full;
  {
    std::lock_guard<std::mutex> lock(pending_mutex_);
    if (resets_.load() != resets_before) {  // reset() holds pending_mutex_ while it counts
      ++views_overtaken_by_reset_;
      input.fruit.clear();
      input.error = "a reset came while the view was being inserted: not mapped";
      return input;
    }
    pending_.push_back({std::move(input.fruit), view.sensor_pose, input.error});
    input.fruit.clear();
    InputTotals& t = input_totals_;
    t.camera_frames += view.source == ViewSource::kCameraFrame ? 1 : 0;
    t.roi_views += view.source == ViewSource::kRoiCloud ? 1 : 0;
    t.fruit_clouds += view.source == ViewSource::kFruitCloud ? 1 : 0;
    t.masked_points += input.masked;
    t.depth_edge_points += input.depth_edges;
    t.veil_points += input.veil;
    t.outlier_points += input.outliers;
    t.non_finite_points += input.non_finite;
    ++t.views;
    last_input_ = input;
    full = pending_.size() >= kMaxPendingViews;
  }
  // Views come faster than updates take them: this caller integrates the oldest one, so the
  // queue stops growing and a call costs at most what it did before views waited.
  if (full) {
    std::lock_guard<std::mutex> lock(map_mutex_);
    integratePending(1);
  }
  return input;
}

void SuperellipsoidEstimator::integratePending(std::size_t max_views) {
  std::size_t n;
  {
    std::lock_guard<std::mutex> lock(pending_mutex_);
    n = std::min(max_views, pending_.size());  // not the views queued meanwhile
  }
  // One view at a time off the front: a view whose integration throws (out of memory, say)
  // loses only itself, and the views behind it never left the queue.
  for (std::size_t k = 0; k < n; ++k) {
    PendingView v;
    {
      std::lock_guard<std::mutex> lock(pending_mutex_);
      if (pending_.empty()) return;  // a reset took them
      v = std::move(pending_.front());
      pending_.erase(pending_.begin());
    }
    const bool input_refused = !v.refused.empty();
    // A view without fruit points (exploring, leaves only) is normal: nothing to integrate, not
    // a refused view.
    const bool no_fruit = !input_refused && v.fruit.empty();
    if (no_fruit) {
      last_ = IntegrationReport();
      ++totals_.views_without_fruit;
    } else if (!input_refused) {
      try {
        last_ = integrator_.integrate(map_, v.fruit, v.sensor_pose);
      } catch (...) {  // the host counts and reports the call that threw
        dirty_ = true;  // the view may have reached some voxels
        ++totals_.views_refused;
        throw;
      }
    } else {
      last_ = IntegrationReport();
      last_.error = std::move(v.refused);
    }
    dirty_ = dirty_ || last_.rays > 0;
    totals_.views_refused += last_.ok() ? 0 : 1;
    totals_.points_skipped += last_.non_finite + last_.out_of_range;
    totals_.rays_outside += last_.outside_map;
    totals_.rays_over_budget += last_.over_budget;
    // Kept for the caller's log (the input stage's refusals were in insertViewReporting's
    // report); beyond the cap they are still in the counters above.
    const bool problem = !input_refused && (!last_.ok() || !last_.warning.empty());
    if (problem && problems_.size() < 2 * kMaxPendingViews) problems_.push_back(last_);
  }
}

std::vector<IntegrationReport> SuperellipsoidEstimator::takeIntegrationProblems() {
  std::lock_guard<std::mutex> lock(map_mutex_);
  std::vector<IntegrationReport> taken;
  taken.swap(problems_);
  return taken;
}

EstimatorStatus SuperellipsoidEstimator::status() const {
  std::lock_guard<std::mutex> lock(map_mutex_);
  EstimatorStatus s = totals_;
  s.blocks = map_.blockCount();
  s.max_blocks = map_.params().maxBlocks();
  s.memory_mb = static_cast<double>(map_.memoryBytes()) / 1048576.0;
  {
    std::lock_guard<std::mutex> pending_lock(pending_mutex_);
    s.input = input_totals_;
    s.points_skipped += input_totals_.non_finite_points;
    s.views_overtaken_by_reset = views_overtaken_by_reset_;
  }
  std::lock_guard<std::mutex> results_lock(results_mutex_);
  s.fruits = accepted_->size();
  s.oversized_clusters = static_cast<std::size_t>(stats_.left_out.oversized);
  s.undersized_points = static_cast<std::size_t>(stats_.left_out.undersized_points);
  return s;
}

std::size_t SuperellipsoidEstimator::pendingViews() const {
  std::lock_guard<std::mutex> lock(pending_mutex_);
  return pending_.size();
}

void SuperellipsoidEstimator::update() {
  std::lock_guard<std::mutex> fit_lock(fit_mutex_);
  bool retarget = false;  // new target settings: the last fits' targets are selected again
  {
    std::lock_guard<std::mutex> lock(live_mutex_);
    if (live_pending_) {
      const PipelineParams pipeline = pipelineWith(live_);
      if (liveFieldsDiffer(pipeline, pipeline_.params())) pipeline_.setParams(pipeline);
      params_.shape_targets = live_.shape_targets;
      params_.targets = live_.targets;
      live_pending_ = false;
      retarget = true;
    }
  }
  SurfaceBlocks surface;  // its blocks' points shared with the extractor, not copied
  double surface_seconds = 0.0;
  bool map_changed = false;
  {
    std::lock_guard<std::mutex> lock(map_mutex_);
    integratePending();
    if (dirty_) {
      const auto start = std::chrono::steady_clock::now();
      surface = surface_extractor_.extractBlocks(map_);
      surface_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      dirty_ = false;
      map_changed = true;
    }
  }
  if (!map_changed) {
    if (retarget) selectTargetsAgain();  // outside the map's lock: views keep coming in
    return;
  }
  // The fit runs on the surface snapshot, with the map free for new views and the last results
  // free for queries.
  if (cancel_) return;
  pipeline_.update(surface, &cancel_);
  if (cancel_) return;  // a reset is waiting (or the estimator is going): store nothing
  std::vector<FruitEstimate> accepted, rejected;
  for (auto& f : pipeline_.takeFruits()) (f.accepted ? accepted : rejected).push_back(std::move(f));
  ShapeTargets targets;
  if (params_.shape_targets) targets = selectShapeTargets(accepted, pipeline_.params().missing.samples, params_.targets);
  {
    std::lock_guard<std::mutex> lock(sightings_mutex_);
    sightings_.update(accepted, rejected);
    sightings_.countViews(&accepted);
  }
  std::lock_guard<std::mutex> lock(results_mutex_);
  accepted_ = std::make_shared<const std::vector<FruitEstimate>>(std::move(accepted));
  rejected_ = std::move(rejected);
  surface_ = std::move(surface);
  targets_ = std::make_shared<const ShapeTargets>(std::move(targets));
  stats_ = pipeline_.lastStats();
  surface_seconds_ = surface_seconds;
}

void SuperellipsoidEstimator::selectTargetsAgain() {
  std::shared_ptr<const std::vector<FruitEstimate>> fruits;
  {
    std::lock_guard<std::mutex> lock(results_mutex_);
    fruits = accepted_;
  }
  ShapeTargets targets;
  if (params_.shape_targets) targets = selectShapeTargets(*fruits, pipeline_.params().missing.samples, params_.targets);
  std::lock_guard<std::mutex> lock(results_mutex_);
  if (accepted_ == fruits) targets_ = std::make_shared<const ShapeTargets>(std::move(targets));
}

std::vector<FruitEstimate> SuperellipsoidEstimator::fruits() const { return *sharedFruits(); }

std::shared_ptr<const std::vector<FruitEstimate>> SuperellipsoidEstimator::sharedFruits() const {
  std::lock_guard<std::mutex> lock(results_mutex_);
  return accepted_;
}

PointList SuperellipsoidEstimator::extraTargets() const { return sharedViewTargets()->points; }

ShapeTargets SuperellipsoidEstimator::viewTargets() const { return *sharedViewTargets(); }

std::shared_ptr<const ShapeTargets> SuperellipsoidEstimator::sharedViewTargets() const {
  static const auto kNone = std::make_shared<const ShapeTargets>();
  if (!targets_on_) return kNone;
  std::lock_guard<std::mutex> lock(results_mutex_);
  return targets_;
}

std::unique_lock<std::mutex> SuperellipsoidEstimator::cancelRunningFit() {
  // A running fit returns at its next cluster instead of finishing; unless the estimator is
  // being destroyed (cancelUpdate), fits resume once the caller is done.
  ++resets_waiting_;
  cancel_ = true;
  std::unique_lock<std::mutex> fit_lock(fit_mutex_);
  if (--resets_waiting_ == 0 && !stopping_) cancel_ = false;
  return fit_lock;
}

void SuperellipsoidEstimator::reset() {
  const std::unique_lock<std::mutex> fit_lock = cancelRunningFit();
  std::lock_guard<std::mutex> map_lock(map_mutex_);
  std::lock_guard<std::mutex> pending_lock(pending_mutex_);
  ++resets_;  // views still in insertView are from before: they drop themselves, counted
  views_overtaken_by_reset_ = 0;
  std::lock_guard<std::mutex> lock(results_mutex_);
  map_.clear();
  pipeline_.reset();
  totals_ = EstimatorStatus();
  last_ = IntegrationReport();
  problems_.clear();
  pending_.clear();  // views from before the reset: never mapped, as if integrated and cleared
  last_input_ = FruitInput();
  input_totals_ = InputTotals();
  dirty_ = false;
  accepted_ = std::make_shared<const std::vector<FruitEstimate>>();
  rejected_.clear();
  surface_ = SurfaceBlocks();
  targets_ = std::make_shared<const ShapeTargets>();
  stats_ = PipelineStats();
  std::lock_guard<std::mutex> sightings_lock(sightings_mutex_);
  sightings_.clear();
}

void SuperellipsoidEstimator::cancelUpdate() {
  stopping_ = true;
  cancel_ = true;
}

namespace {

void removeStale(const std::string& path, std::string* warning) {
  const std::vector<std::string> removed = removeStaleTemporaries(path);
  if (!warning) return;
  warning->clear();
  for (const auto& r : removed) *warning += (warning->empty() ? "removed the temporary file of an interrupted save: " : ", ") + r;
}

}  // namespace

bool SuperellipsoidEstimator::saveMap(const std::string& path, std::string* error, std::string* warning) {
  removeStale(path, warning);
  std::string bytes;
  std::vector<CarriedSightings> carried;
  {
    std::lock_guard<std::mutex> lock(map_mutex_);
    integratePending();
    map_.serialize(&bytes);
    // The fruits' view counts after the map, taken with it (a load cannot swap the map between
    // the two). Views integrated since the last update are in the map but matched to no fruit
    // yet: after a load they count from then on.
    std::lock_guard<std::mutex> sightings_lock(sightings_mutex_);
    carried = sightings_.carried();
  }
  appendCarriedSightings(carried, &bytes);
  return writeFileAtomically(path, bytes, error);
}

bool SuperellipsoidEstimator::loadMap(const std::string& path, std::string* error, std::string* warning) {
  removeStale(path, warning);
  TsdfMap loaded(params_.map);  // read outside the lock: the map keeps taking views meanwhile
  std::string rest;
  if (!loaded.load(path, error, &rest)) return false;
  if (loaded.params().voxel_size != params_.map.voxel_size) {
    if (error)
      *error = path + ": voxel size " + std::to_string(loaded.params().voxel_size) + " m differs from the map's " +
               std::to_string(params_.map.voxel_size) + " m";
    return false;
  }
  std::vector<CarriedSightings> carried;
  std::string carried_error;
  if (!readCarriedSightings(rest, &carried, &carried_error) && warning) {
    *warning += std::string(warning->empty() ? "" : "; ") + path + ": " + carried_error +
                "; the map is loaded and its fruits count views from the load on";
  }
  // A fit running on the old map's surface would store and count fruits of a map that is gone.
  const std::unique_lock<std::mutex> fit_lock = cancelRunningFit();
  std::lock_guard<std::mutex> lock(map_mutex_);
  integratePending();  // into the map being replaced, as they came before the load
  map_ = std::move(loaded);
  dirty_ = true;  // the next update() fits the loaded map
  // Its fruits count the views the saved map had fused, and those from the load on.
  std::lock_guard<std::mutex> sightings_lock(sightings_mutex_);
  sightings_.carryOver(std::move(carried));
  return true;
}

std::map<int, FruitSightings> SuperellipsoidEstimator::sightings() const {
  std::lock_guard<std::mutex> lock(sightings_mutex_);
  return sightings_.sightings();
}

bool SuperellipsoidEstimator::exportFruits(const std::string& path, std::string* error, std::string* warning,
                                           std::size_t* written) const {
  removeStale(path, warning);
  const std::vector<FruitEstimate> now = fruits();
  if (written != nullptr) *written = now.size();
  return writeFruitReport(path, now, sightings(), error);
}

std::vector<FruitEstimate> SuperellipsoidEstimator::estimates() const {
  std::lock_guard<std::mutex> lock(results_mutex_);
  std::vector<FruitEstimate> all = *accepted_;
  all.insert(all.end(), rejected_.begin(), rejected_.end());
  return all;
}

PointList SuperellipsoidEstimator::surface() const {
  return surfaceBlocks().cloud();  // concatenated outside the lock
}

SurfaceBlocks SuperellipsoidEstimator::surfaceBlocks() const {
  std::lock_guard<std::mutex> lock(results_mutex_);
  return surface_;  // shares the points
}

FruitInput SuperellipsoidEstimator::lastInput() const {
  std::lock_guard<std::mutex> lock(pending_mutex_);
  return last_input_;
}

IntegrationReport SuperellipsoidEstimator::lastIntegration() const {
  std::lock_guard<std::mutex> lock(map_mutex_);
  return last_;
}

PipelineStats SuperellipsoidEstimator::lastPipelineStats() const {
  std::lock_guard<std::mutex> lock(results_mutex_);
  return stats_;
}

double SuperellipsoidEstimator::lastSurfaceSeconds() const {
  std::lock_guard<std::mutex> lock(results_mutex_);
  return surface_seconds_;
}

}  // namespace host
}  // namespace fruit_shape_completion
