#include <fruit_shape_completion/fruit_center.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/spatial_hash_grid.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <unordered_map>

namespace fruit_shape_completion {

namespace {

constexpr double kTrackCell = 0.01;  // cell size for matching clusters between updates

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

std::unordered_set<std::uint64_t> occupiedCells(const PointList& points) {
  std::unordered_set<std::uint64_t> cells;
  cells.reserve(points.size());
  for (const auto& p : points)
    cells.insert(SpatialHashGrid::packKey(static_cast<std::int64_t>(std::floor(p.x() / kTrackCell)),
                                          static_cast<std::int64_t>(std::floor(p.y() / kTrackCell)),
                                          static_cast<std::int64_t>(std::floor(p.z() / kTrackCell))));
  return cells;
}

}  // namespace

void PipelineParams::validate() const {
  if (!(clustering.tolerance > 0.0) || !std::isfinite(clustering.tolerance))
    throw std::invalid_argument("cluster tolerance must be a finite value > 0");
  if (clustering.min_size < 1 || clustering.max_size < clustering.min_size)
    throw std::invalid_argument("cluster sizes must satisfy 1 <= min_size <= max_size");
  if (!(normals.radius > 0.0) || !std::isfinite(normals.radius))
    throw std::invalid_argument("normal radius must be a finite value > 0");
  if (!(center_lambda >= 0.0) || !std::isfinite(center_lambda))
    throw std::invalid_argument("center lambda must be a finite value >= 0");
  if (missing.samples < 0) throw std::invalid_argument("missing-surface samples must be >= 0");
  if (!(missing.threshold > 0.0) || !std::isfinite(missing.threshold))
    throw std::invalid_argument("missing-surface threshold must be a finite value > 0");
  fit.validate();
}

FruitShapePipeline::FruitShapePipeline(const PipelineParams& params) : params_(params) {
  params_.validate();
}

void FruitShapePipeline::reset() {
  tracks_.clear();
  fruits_.clear();
  stats_ = PipelineStats();
  next_id_ = 0;
}

FruitEstimate FruitShapePipeline::estimateCluster(const PointList& points, int id,
                                                  const Track* previous) {
  FruitEstimate est;
  est.id = id;
  est.n_points = static_cast<int>(points.size());
  est.refitted = true;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
    sum += p;
  }
  est.points_centroid = sum / std::max<size_t>(1, points.size());
  est.bbox_volume = points.empty() ? 0.0 : (hi - lo).prod();
  est.shape.t = est.points_centroid;

  const SurfaceNormals normals = estimateNormals(points, params_.normals, est.points_centroid);
  const ClusterShapeCheck check = checkClusterShape(points, normals.normals);
  if (!check.ok) {
    est.reason = check.reason;
    return est;
  }
  est.center_prior = estimateFruitCenter(points, normals.normals, params_.center_lambda);
  const Superellipsoid* warm =
      previous != nullptr && previous->estimate.accepted ? &previous->estimate.shape : nullptr;
  const FitResult fit = fitSuperellipsoid(points, est.center_prior, params_.fit, warm);
  est.shape = fit.shape;
  est.converged = fit.converged;
  est.accepted = fit.accepted;
  est.reason = fit.reason;
  est.rms = fit.rms;
  est.iterations = fit.iterations;
  est.fit_seconds = fit.seconds;
  est.volume = fit.shape.volume();
  if (est.accepted && params_.missing.samples > 0) {
    const SpatialHashGrid grid(points, params_.missing.threshold);
    est.missing_surface = predictMissingSurface(est.shape, grid, params_.missing);
  }
  return est;
}

const std::vector<FruitEstimate>& FruitShapePipeline::update(const PointList& surface_cloud) {
  const auto start = std::chrono::steady_clock::now();
  stats_ = PipelineStats();
  stats_.input_points = static_cast<int>(surface_cloud.size());
  PointList finite;
  finite.reserve(surface_cloud.size());
  for (const auto& p : surface_cloud) {
    if (p.allFinite())
      finite.push_back(p);
    else
      ++stats_.non_finite_points;
  }

  const auto clusters = euclideanClusters(finite, params_.clustering);
  stats_.clusters = static_cast<int>(clusters.size());

  std::vector<Track> next(clusters.size());
  std::vector<PointList> cluster_points(clusters.size());
  for (size_t c = 0; c < clusters.size(); ++c) {
    PointList& pts = cluster_points[c];
    pts.reserve(clusters[c].size());
    for (int i : clusters[c]) pts.push_back(finite[i]);
    next[c].signature = pointSetSignature(pts);
    next[c].cells = occupiedCells(pts);
  }

  // Match clusters to previous fruits by shared cells, largest overlap first, one to one.
  std::unordered_map<std::uint64_t, int> cell_owner;
  for (size_t k = 0; k < tracks_.size(); ++k)
    for (auto cell : tracks_[k].cells) cell_owner.emplace(cell, static_cast<int>(k));
  struct Pair {
    int overlap, cluster, track;
  };
  std::vector<Pair> pairs;
  for (size_t c = 0; c < next.size(); ++c) {
    std::unordered_map<int, int> counts;
    for (auto cell : next[c].cells) {
      auto it = cell_owner.find(cell);
      if (it != cell_owner.end()) ++counts[it->second];
    }
    for (const auto& kv : counts) pairs.push_back({kv.second, static_cast<int>(c), kv.first});
  }
  std::sort(pairs.begin(), pairs.end(), [](const Pair& l, const Pair& r) {
    return l.overlap != r.overlap ? l.overlap > r.overlap
                                  : (l.cluster != r.cluster ? l.cluster < r.cluster : l.track < r.track);
  });
  std::vector<int> match(next.size(), -1);
  std::vector<char> track_used(tracks_.size(), 0);
  for (const auto& p : pairs) {
    if (match[p.cluster] >= 0 || track_used[p.track]) continue;
    match[p.cluster] = p.track;
    track_used[p.track] = 1;
  }

  for (size_t c = 0; c < next.size(); ++c) {
    const PointList& pts = cluster_points[c];
    const Track* prev = match[c] >= 0 ? &tracks_[match[c]] : nullptr;
    if (prev != nullptr && prev->signature == next[c].signature &&
        prev->estimate.n_points == static_cast<int>(pts.size())) {
      next[c].estimate = prev->estimate;
      next[c].estimate.refitted = false;
    } else {
      const int id = prev != nullptr ? prev->estimate.id : next_id_++;
      next[c].estimate = estimateCluster(pts, id, prev);
      ++stats_.fitted;
    }
    if (next[c].estimate.accepted) ++stats_.accepted;
  }

  tracks_.swap(next);
  fruits_.clear();
  for (const auto& t : tracks_) fruits_.push_back(t.estimate);
  stats_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return fruits_;
}

}  // namespace fruit_shape_completion
