#include <fruit_shape_completion/center_uncertainty.h>
#include <fruit_shape_completion/fruit_center.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/grid_cell.h>
#include <fruit_shape_completion/parallel_jobs.h>
#include <fruit_shape_completion/shape_targets.h>
#include <fruit_shape_completion/volume_interval.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <unordered_map>

namespace fruit_shape_completion {

namespace {

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::uint64_t mix(std::uint64_t x) {  // splitmix64 finaliser
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// Order-independent signature of a point set: sum of per-point hashes of the exact coordinates.
std::uint64_t pointSetSignature(const PointList& points) {
  std::uint64_t sum = 0;
  for (const auto& p : points) {
    std::uint64_t h = 0;
    for (int k = 0; k < 3; ++k) {
      std::uint64_t bits;
      const double v = p[k];
      std::memcpy(&bits, &v, sizeof(bits));
      h = mix(h ^ bits);
    }
    sum += h;
  }
  return mix(sum ^ points.size());
}

}  // namespace

namespace {

// The cluster's points and what they alone say: their count, centroid and bounding-box volume.
void describeCluster(const PointList& points, FruitEstimate* est) {
  est->n_points = static_cast<int>(points.size());
  est->points = points;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
    sum += p;
  }
  est->points_centroid = sum / std::max<size_t>(1, points.size());
  est->bbox_volume = points.empty() ? 0.0 : (hi - lo).prod();
}

}  // namespace

void PipelineParams::validate() const {
  if (!(clustering.tolerance > 0.0) || !std::isfinite(clustering.tolerance))
    throw std::invalid_argument("cluster tolerance must be a finite value > 0");
  if (clustering.min_size < 1 || clustering.max_size < clustering.min_size)
    throw std::invalid_argument("cluster sizes must satisfy 1 <= min_size <= max_size");
  if (!(normals.radius > 0.0) || !std::isfinite(normals.radius))
    throw std::invalid_argument("normal radius must be a finite value > 0");
  if (!(normals.max_edge_offset >= 0.0 && normals.max_edge_offset < 1.0))
    throw std::invalid_argument("normal_max_edge_offset must be in [0, 1)");
  if (!(center_lambda >= 0.0) || !std::isfinite(center_lambda))
    throw std::invalid_argument("center lambda must be a finite value >= 0");
  if (!std::isfinite(center_rim_margin)) throw std::invalid_argument("center_rim_margin must be finite");
  // Bounded: each fruit keeps its samples (and every one may become a planner target).
  if (missing.samples < 0 || missing.samples > 100000)
    throw std::invalid_argument("missing-surface samples must be in [0, 100000]");
  if (threads < 1 || threads > 64) throw std::invalid_argument("fit threads must be in [1, 64]");
  if (!(refit_tolerance >= 0.0) || !std::isfinite(refit_tolerance))
    throw std::invalid_argument("refit tolerance must be a finite value >= 0");
  if (!(missing.threshold > 0.0) || !std::isfinite(missing.threshold))
    throw std::invalid_argument("missing-surface threshold must be a finite value > 0");
  if (!(one_fruit_max_rms >= fit.max_rms) || !std::isfinite(one_fruit_max_rms))
    throw std::invalid_argument("one_fruit_max_rms must be a finite value >= the fit's max_rms");
  if (!(split_rms > 0.0) || !(split_rms <= fit.max_rms))
    throw std::invalid_argument("split_rms must be in (0, the fit's max_rms]");
  fit.validate();
}

void PipelineStats::addJob(const PipelineStats& job) {
  fitted += job.fitted;
  kept += job.kept;
  splits += job.splits;
  prior_seconds += job.prior_seconds;
  fit_seconds += job.fit_seconds;
  missing_seconds += job.missing_seconds;
}

FruitShapePipeline::FruitShapePipeline(const PipelineParams& params) : params_(params) {
  params_.validate();
}

void FruitShapePipeline::reset() {
  local_ready_ = false;
  pending_changed_.clear();
  tracks_.clear();
  fruits_.clear();
  stats_ = PipelineStats();
  next_id_ = 0;
}

std::vector<Eigen::Vector3d> FruitShapePipeline::normalsOf(const PointList& points, PipelineStats* stats) const {
  const auto start = std::chrono::steady_clock::now();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points) centroid += p / static_cast<double>(points.size());
  std::vector<Eigen::Vector3d> normals = estimateNormals(points, params_.normals, centroid).normals;
  stats->prior_seconds += secondsSince(start);
  return normals;
}

FruitEstimate FruitShapePipeline::estimateCluster(const PointList& points, const std::vector<Eigen::Vector3d>& normals,
                                                  int id, const Track* previous, PipelineStats* stats) const {
  FruitEstimate est;
  est.id = id;
  est.refitted = true;
  describeCluster(points, &est);
  est.shape.t = est.points_centroid;

  const auto prior_start = std::chrono::steady_clock::now();
  const ClusterShapeCheck check = checkClusterShape(points, normals);
  if (!check.ok) {
    est.reason = check.reason;
    return est;
  }
  CenterPriorBlend blend;
  blend.rim_margin = params_.center_rim_margin;
  est.center_prior = blendedFruitCenter(points, normals, params_.center_lambda, blend);
  stats->prior_seconds += secondsSince(prior_start);
  const bool warm = previous != nullptr && previous->estimate.accepted;
  const Superellipsoid start = warm ? previous->estimate.fittedShape() : Superellipsoid();
  const FitResult fit = fitSuperellipsoid(points, est.center_prior, params_.fit, warm ? &start : nullptr);
  est.shape = fit.shape;
  est.noise_scale = fit.noise_scale;
  est.converged = fit.converged;
  est.accepted = fit.accepted;
  est.reason = fit.reason;
  est.rms = fit.rms;
  est.iterations = fit.iterations;
  est.fit_seconds = fit.seconds;
  stats->fit_seconds += fit.seconds;
  est.volume = fit.shape.volume();
  return est;
}

FruitEstimate FruitShapePipeline::keptEstimate(const FruitEstimate& fit, const PointList& points) {
  FruitEstimate e = fit;
  describeCluster(points, &e);
  e.refitted = false;
  return e;
}

void FruitShapePipeline::predictMissing(FruitEstimate* e, PipelineStats* stats) const {
  e->missing_surface.clear();
  e->missing_normals.clear();
  if (!e->accepted) return;
  const auto start = std::chrono::steady_clock::now();
  // With no samples asked for (no targets wanted), the seen share that the volume interval and
  // the centre radius are read from is still measured, on the default samples, which are then
  // not kept.
  MissingSurfaceParams measured = params_.missing;
  if (measured.samples <= 0) measured.samples = MissingSurfaceParams().samples;
  PointList surface = predictMissingSurface(e->shape, e->points, measured);
  const double seen = seenCoverage(surface.size(), measured.samples);
  if (params_.missing.samples > 0) {
    // Computed once per fit, not at every hand-over of the targets.
    PointList normals;
    normals.reserve(surface.size());
    for (const auto& s : surface) normals.push_back(outwardNormal(e->shape, s));
    e->missing_surface = std::move(surface);
    e->missing_normals = std::move(normals);
  }
  // The fit's own solution: whether it rests on min_axis, and the spread its residuals and
  // Jacobian imply, are the least-squares fit's, not its shrunk copy's.
  const Superellipsoid se = e->fittedShape();
  const bool at_bound = std::min({se.a, se.b, se.c}) <= 1.025 * params_.fit.min_axis;
  e->log_volume_spread = logVolumeSpread(e->points, se);
  e->seen_share = seen;
  e->size_at_bound = at_bound;
  const VolumeInterval ci = volumeInterval90(*e);
  e->volume_lo = ci.lo;
  e->volume_hi = ci.hi;
  e->center_r90 = centerRadius90(seen, e->rms, at_bound);
  stats->missing_seconds += secondsSince(start);
}

std::vector<FruitShapePipeline::Track> FruitShapePipeline::fitChangedCluster(
    const PointList& pts, const std::unordered_set<std::uint64_t>& cells, const std::vector<char>& reused,
    PipelineStats* stats) const {
  std::vector<Eigen::Vector3d> normals;
  std::optional<FruitEstimate> whole;  // fitted on the way, if so
  std::vector<Track> out =
      params_.refit_tolerance > 0.0 ? splitAsBefore(pts, cells, reused, &normals, &whole, stats) : std::vector<Track>();
  if (out.empty()) {
    if (normals.empty()) normals = normalsOf(pts, stats);
    // A fruit whose rough fit was tried split before and stayed whole is not tried again until
    // its cluster has grown: the same split would be refused again.
    const int previous = bestOverlap(cells);
    const std::size_t checked = previous >= 0 ? tracks_[static_cast<std::size_t>(previous)].rough_checked_points : 0;
    const bool split_rough = static_cast<double>(pts.size()) > (1.0 + kRecheckGrowth) * static_cast<double>(checked);
    const int fitted_before = stats->fitted;
    Parts parts = estimateWithSplit(pts, normals, 0, stats, &cells, whole ? &*whole : nullptr, split_rough);
    const bool tried = stats->fitted - fitted_before >= 2;  // a split's two halves were fitted
    for (auto& part : parts) {
      Track t;
      if (parts.size() == 1 && part.second.accepted && part.second.rms > params_.split_rms)
        t.rough_checked_points = tried ? pts.size() : checked;
      t.estimate = std::move(part.second);
      t.fitted_points = part.first.size();
      t.cells = part.first.size() == pts.size() ? cells : occupiedCells(part.first);  // unsplit: the cluster's own cells
      t.split_points = parts.size() > 1 ? pts.size() : 0;
      out.push_back(std::move(t));
    }
  }
  // Unseen surfaces of the final fruits only (not of trial fits).
  for (auto& t : out) predictMissing(&t.estimate, stats);
  return out;
}

const std::vector<FruitEstimate>& FruitShapePipeline::update(const PointList& surface_cloud,
                                                             const std::atomic<bool>* cancel) {
  return run(&surface_cloud, nullptr, cancel);
}

const std::vector<FruitEstimate>& FruitShapePipeline::update(const SurfaceBlocks& surface,
                                                             const std::atomic<bool>* cancel) {
  return run(nullptr, &surface, cancel);
}

const std::vector<FruitEstimate>& FruitShapePipeline::run(const PointList* cloud, const SurfaceBlocks* blocks,
                                                          const std::atomic<bool>* cancel) {
  const auto start = std::chrono::steady_clock::now();
  stats_ = PipelineStats();
  if (blocks != nullptr && blocks->points_in_blocks)  // else never local: nothing to remember
    pending_changed_.insert(pending_changed_.end(), blocks->changed.begin(), blocks->changed.end());
  // Around the changed blocks only, when the tracks know their blocks of this size.
  const bool local = blocks != nullptr && local_ready_ && !blocks->all_changed && blocks->points_in_blocks &&
                     blocks->block_size == local_block_size_ && blocks->block_size > params_.clustering.tolerance;
  PointList assembled;  // the whole cloud from the blocks, when all of it is clustered
  if (!local && cloud == nullptr) {
    assembled = blocks->cloud();
    cloud = &assembled;
  }
  PointList filtered;  // the finite points: a copy only when some point must go
  PointList gathered;  // local: the points around the changed blocks
  const auto cluster_start = std::chrono::steady_clock::now();
  std::vector<Track> untouched;  // fruits the changed blocks do not reach: carried over as they are
  std::vector<std::vector<int>> clusters;
  if (local) {
    stats_.input_points = static_cast<int>(blocks->size());
    clusters = localClusters(*blocks, &gathered, &untouched);
  } else {
    stats_.input_points = static_cast<int>(cloud->size());
    for (const auto& p : *cloud) stats_.non_finite_points += p.allFinite() ? 0 : 1;
    if (stats_.non_finite_points > 0) {
      filtered.reserve(cloud->size());
      for (const auto& p : *cloud)
        if (p.allFinite()) filtered.push_back(p);
    }
    clusters = euclideanClusters(stats_.non_finite_points > 0 ? filtered : *cloud, params_.clustering,
                                 &stats_.left_out);
  }
  // What the clusters index.
  const PointList& finite = local ? gathered : stats_.non_finite_points > 0 ? filtered : *cloud;
  stats_.local = local;
  stats_.clusters = static_cast<int>(clusters.size());
  stats_.cluster_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - cluster_start).count();
  // A cancelled update leaves the tracks as they were.
  auto abandon = [&]() -> const std::vector<FruitEstimate>& {
    for (auto& t : untouched) tracks_.push_back(std::move(t));
    return fruits_;
  };

  std::vector<Track> next;      // fruits carried over unchanged
  std::vector<Track> pending;   // fruits fitted now, ids still to assign
  std::vector<char> reused(tracks_.size(), 0);
  struct FitJob {
    PointList points;
    std::uint64_t signature;
    std::unordered_set<std::uint64_t> cells;
  };
  std::vector<FitJob> jobs;  // changed clusters no previous fit explains
  std::vector<std::size_t> kept_at;  // in next: re-observed fruits whose fit still explains them
  for (const auto& cluster : clusters) {
    if (cancel && cancel->load()) return abandon();
    PointList pts;
    pts.reserve(cluster.size());
    for (int i : cluster) pts.push_back(finite[i]);
    const std::uint64_t signature = pointSetSignature(pts);
    // An unchanged cluster keeps its fruits (one, or several after a split) as they are.
    bool unchanged = false;
    for (std::size_t k = 0; k < tracks_.size(); ++k)
      if (!reused[k] && tracks_[k].cluster_signature == signature && tracks_[k].cluster_points == pts.size()) {
        reused[k] = 1;
        next.push_back(tracks_[k]);
        next.back().estimate.refitted = false;
        unchanged = true;
      }
    if (unchanged) continue;
    std::unordered_set<std::uint64_t> cells = occupiedCells(pts);
    const int kept = params_.refit_tolerance > 0.0 ? stillExplainedBy(pts, cells, reused) : -1;
    if (kept >= 0) {
      // The same fruit seen again: new points, the old fit, its unseen surface recomputed.
      reused[kept] = 1;
      Track t = tracks_[kept];
      t.estimate = keptEstimate(t.estimate, pts);
      t.cluster_signature = signature;
      t.cluster_points = pts.size();
      t.cells = cells;
      t.split_points = 0;  // a cluster of its own now
      kept_at.push_back(next.size());  // its unseen surface is recomputed beside the fits
      next.push_back(std::move(t));
      ++stats_.kept;
      continue;
    }
    jobs.push_back({std::move(pts), signature, std::move(cells)});
  }
  // The changed clusters' fits, independent of one another (their fruits join in cluster
  // order), then the kept fruits' unseen surfaces.
  std::vector<std::vector<Track>> fitted(jobs.size());
  std::vector<PipelineStats> job_stats(jobs.size() + kept_at.size());
  // Largest clusters first: the longest fits start early and the short ones fill in beside
  // them, so the threads finish together.
  std::vector<std::size_t> order(jobs.size() + kept_at.size());
  for (std::size_t j = 0; j < order.size(); ++j) order[j] = j;
  std::stable_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(jobs.size()),
                   [&](std::size_t l, std::size_t r) { return jobs[l].points.size() > jobs[r].points.size(); });
  ThreadBudget budget(params_.threads);
  struct Lend {  // the budget is the split's to borrow from while the jobs run, and only then
    ThreadBudget*& to;
    Lend(ThreadBudget*& to, ThreadBudget* budget) : to(to) { to = budget; }
    ~Lend() { to = nullptr; }
  } lend(budget_, &budget);
  try {
    runParallelJobs(
        order.size(), params_.threads,
        [&](std::size_t i) {
          const ThreadBudget::Busy busy(budget);
          const std::size_t j = order[i];
          if (j < jobs.size())
            fitted[j] = fitChangedCluster(jobs[j].points, jobs[j].cells, reused, &job_stats[j]);
          else
            predictMissing(&next[kept_at[j - jobs.size()]].estimate, &job_stats[j]);
        },
        cancel);
  } catch (...) {  // out of memory, say: the fruits stay as they were, all clustered next time
    abandon();
    local_ready_ = false;
    throw;
  }
  if (cancel && cancel->load()) return abandon();
  for (std::size_t j = 0; j < job_stats.size(); ++j) {
    if (j < jobs.size())
      for (auto& t : fitted[j]) {
        t.cluster_signature = jobs[j].signature;
        t.cluster_points = jobs[j].points.size();
        pending.push_back(std::move(t));
      }
    stats_.addJob(job_stats[j]);
  }

  assignIds(&pending, &reused);
  for (auto& t : pending) next.push_back(std::move(t));
  // The blocks of the fruits formed now, for the next local update.
  if (blocks != nullptr && blocks->points_in_blocks && blocks->block_size > 0.0) {
    const double inv = 1.0 / blocks->block_size;
    for (auto& t : next) {  // in a local update, the fruits around the changed blocks only
      std::unordered_set<std::uint64_t> keys;
      t.blocks.clear();
      for (const auto& p : t.estimate.points) {
        const GridCell c = cellOf(p, inv);
        if (keys.insert(packCellKey(c)).second) t.blocks.push_back(c);
      }
    }
    local_ready_ = true;
    local_block_size_ = blocks->block_size;
    pending_changed_.clear();
  } else {
    local_ready_ = false;
  }
  for (auto& t : untouched) next.push_back(std::move(t));
  std::stable_sort(next.begin(), next.end(),
                   [](const Track& l, const Track& r) { return l.estimate.n_points > r.estimate.n_points; });
  for (const auto& t : next) stats_.accepted += t.estimate.accepted;

  tracks_.swap(next);
  fruits_.clear();
  for (const auto& t : tracks_) fruits_.push_back(t.estimate);
  stats_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return fruits_;
}

}  // namespace fruit_shape_completion
