#include <fruit_shape_completion/neighbourhood_statistics.h>
#include <fruit_shape_completion/parallel_parts.h>
#include <fruit_shape_completion/spatial_hash_grid.h>
#include <fruit_shape_completion/tsdf_integrator.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <memory>
#include <mutex>

namespace fruit_shape_completion {

namespace {

// Casts the rays of one view into the map: each ray updates the voxels it crosses within its
// band (from `tau` before the end point, or from the sensor with carve_free_space, to
// `back_len` behind it).
//
// The band voxels of a full frame (tens of MB) mostly miss the caches, and a ray that applied
// its updates as it went would wait on each miss in turn. So the traversal only queues the
// updates and prefetches their voxels; every kQueueFlush updates the queue is applied in
// order. The misses overlap, and the map ends as with one update after another.
class BandCaster {
 public:
  BandCaster(TsdfMap& map, const TsdfIntegratorParams& params, double tau)
      : map_(map),
        params_(params),
        tau_(tau),
        vs_(map.voxelSize()),
        inv_vs_(1.0 / map.voxelSize()),
        nps_(map.voxelsPerSide()),
        layout_x_(map.layout().xTable()),
        layout_y_(map.layout().yTable()),
        layout_z_(map.layout().zTable()),
        crop_(map.params().use_crop_box),
        queue_(kQueueFlush + 1024) {}

  std::size_t rays = 0, voxel_updates = 0, partly_dropped_rays = 0;

  void cast(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
            double range, double w_ray, double back_len);
  // The same for a ray whose band lies inside `block` (bandVoxels() one voxel or more from its
  // faces): the map's block table is not touched, so casters on disjoint blocks may run
  // concurrently. Should rounding carry the traversal out of the block anyway, the ray ends.
  void castWithin(TsdfBlock* block, const VoxelIndex& block_origin, const Eigen::Vector3d& p,
                  const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double range, double w_ray,
                  double back_len) {
    fixed_block_ = block;
    fixed_origin_ = block_origin;
    cast(p, origin, dir, range, w_ray, back_len);
    fixed_block_ = nullptr;
  }
  // The first and last voxel of a ray's band (what cast() traverses between).
  void bandVoxels(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                  double range, double back_len, VoxelIndex* first, VoxelIndex* last) const {
    Eigen::Vector3d a, b;
    bandEnds(p, origin, dir, range, back_len, &a, &b);
    *first = a.array().floor().cast<std::int64_t>();
    *last = b.array().floor().cast<std::int64_t>();
  }
  // Applies what is still queued.
  void finish() { flush(); }

 private:
  struct QueuedUpdate {
    TsdfBlock* block;
    std::uint32_t idx;
    float sdf;
    double weight;
  };
  static constexpr std::size_t kQueueFlush = 1024;

  void flush() {
    const double max_weight = params_.max_weight;
    for (std::size_t k = 0; k < queued_; ++k) {
      const QueuedUpdate& u = queue_[k];
      u.block->update(u.idx, u.sdf, u.weight, max_weight);
    }
    queued_ = 0;
  }
  // The band's start and end in voxel units: one computation for cast() and bandVoxels(), so
  // the parallel pass classifies a ray by exactly the voxels its traversal will visit.
  void bandEnds(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double range,
                double back_len, Eigen::Vector3d* a, Eigen::Vector3d* b) const {
    const Eigen::Vector3d s = params_.carve_free_space ? origin : Eigen::Vector3d(p - dir * std::min(tau_, range));
    *a = s * inv_vs_;
    *b = (p + dir * back_len) * inv_vs_;
  }
  TsdfBlock* enterBlock(const VoxelIndex& voxel, VoxelIndex* block_origin) {
    if (fixed_block_ != nullptr) {
      *block_origin = fixed_origin_;
      return fixed_block_;
    }
    *block_origin = map_.blockOriginOf(voxel);
    return map_.blockForUpdate(*block_origin);
  }

  TsdfMap& map_;
  const TsdfIntegratorParams& params_;
  const double tau_, vs_, inv_vs_;
  const int nps_;
  const std::uint32_t *layout_x_, *layout_y_, *layout_z_;
  const bool crop_;
  std::vector<QueuedUpdate> queue_;
  std::size_t queued_ = 0;
  TsdfBlock* fixed_block_ = nullptr;  // castWithin()
  VoxelIndex fixed_origin_;
};

void BandCaster::cast(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                      double range, double w_ray, double back_len) {
  ++rays;

  // Amanatides-Woo traversal of the voxels from a to b, in voxel units. Everything the loop
  // carries is a scalar (per-axis arrays indexed by the step axis would live on the stack);
  // the block is looked up only when the ray crosses into the next one.
  Eigen::Vector3d a, b;
  bandEnds(p, origin, dir, range, back_len, &a, &b);
  const Eigen::Vector3d d = b - a;
  const VoxelIndex first = a.array().floor().cast<std::int64_t>();
  const VoxelIndex last = b.array().floor().cast<std::int64_t>();
  const double inf = std::numeric_limits<double>::infinity();
  auto setup = [&](int k, int& step, double& t_max, double& t_delta) {
    step = d[k] > 0 ? 1 : (d[k] < 0 ? -1 : 0);
    if (step == 0) {
      t_max = t_delta = inf;
    } else {
      const double boundary = static_cast<double>(first[k] + (step > 0 ? 1 : 0));
      const double inv = 1.0 / d[k];
      t_max = (boundary - a[k]) * inv;
      t_delta = std::abs(inv);
    }
  };
  int sx, sy, sz;
  double tx, ty, tz, dtx, dty, dtz;
  setup(0, sx, tx, dtx);
  setup(1, sy, ty, dty);
  setup(2, sz, tz, dtz);
  VoxelIndex block_origin;
  TsdfBlock* block = enterBlock(first, &block_origin);
  int lx = static_cast<int>(first.x() - block_origin.x());
  int ly = static_cast<int>(first.y() - block_origin.y());
  int lz = static_cast<int>(first.z() - block_origin.z());
  double sdf = range - (map_.voxelCenter(first) - origin).dot(dir);  // projective distance
  const double dsx = sx * vs_ * dir.x(), dsy = sy * vs_ * dir.y(), dsz = sz * vs_ * dir.z();
  const std::int64_t steps = (last - first).cwiseAbs().sum();
  // Room for every voxel of this ray: a free-space ray can cross thousands.
  if (queued_ + static_cast<std::size_t>(steps) + 1 > queue_.size()) {
    flush();
    if (static_cast<std::size_t>(steps) + 1 > queue_.size()) queue_.resize(static_cast<std::size_t>(steps) + 1);
  }
  QueuedUpdate* out = queue_.data() + queued_;
  const double drop_start = -vs_, drop_scale = 1.0 / (tau_ - vs_);
  const bool drop_off = params_.drop_off;
  const float sdf_max = static_cast<float>(tau_);
  bool dropped = false;
  for (std::int64_t n = 0;; ++n) {
    if (sdf >= -back_len) {
      double w = w_ray;
      if (drop_off && sdf < drop_start) w *= (tau_ + sdf) * drop_scale;
      if (w > 0.0) {
        if (block == nullptr ||
            (crop_ && !map_.insideCropBox(map_.voxelCenter(block_origin + VoxelIndex(lx, ly, lz))))) {
          dropped = true;
        } else {
          const std::uint32_t idx = layout_x_[lx] + layout_y_[ly] + layout_z_[lz];
          block->touchForWrite(idx);
          __builtin_prefetch(&block->voxels[idx], 1);
          *out++ = {block, idx, std::min(static_cast<float>(sdf), sdf_max), w};
        }
      }
    }
    if (n == steps) break;
    // The axis whose boundary comes first (ties: x before y before z).
    int* l;
    if (tx <= ty && tx <= tz) {
      if (tx > 1.0) break;
      tx += dtx;
      sdf -= dsx;
      lx += sx;
      l = &lx;
    } else if (ty <= tz) {
      if (ty > 1.0) break;
      ty += dty;
      sdf -= dsy;
      ly += sy;
      l = &ly;
    } else {
      if (tz > 1.0) break;
      tz += dtz;
      sdf -= dsz;
      lz += sz;
      l = &lz;
    }
    if (static_cast<unsigned>(*l) >= static_cast<unsigned>(nps_)) {
      if (fixed_block_ != nullptr) break;  // castWithin: never another block
      const VoxelIndex voxel = block_origin + VoxelIndex(lx, ly, lz);
      block = enterBlock(voxel, &block_origin);
      lx = static_cast<int>(voxel.x() - block_origin.x());
      ly = static_cast<int>(voxel.y() - block_origin.y());
      lz = static_cast<int>(voxel.z() - block_origin.z());
    }
  }
  const std::size_t added = static_cast<std::size_t>(out - (queue_.data() + queued_));
  queued_ += added;
  voxel_updates += added;
  if (dropped) ++partly_dropped_rays;
  if (queued_ >= kQueueFlush) flush();
}

// Clouds of at least this many merged points are worth more than one thread.
constexpr std::size_t kParallelFrom = 20000;

}  // namespace

struct TsdfIntegrator::Scratch {
  struct Merged {  // the points of one voxel
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int count = 0;
  };
  std::vector<std::uint64_t> keys;
  FlatHashMap<int> slot;
  std::vector<Merged> merged;
  PointList ends;
  std::vector<double> knn;
  std::vector<Eigen::Vector3d> normals;
  std::vector<char> outlier;
  std::vector<int> ray_block;
  std::vector<VoxelIndex> ray_home;  // the 2-thread pass's block of each ray
  SpatialHashGrid grid;  // the neighbourhood pass's
};

void TsdfIntegrator::releaseScratch() const {
  std::lock_guard<std::mutex> lock(scratch_.mutex);
  scratch_.data.reset();
}

void TsdfIntegratorParams::validate() const {
  if (!(truncation_voxels >= 1.0) || !std::isfinite(truncation_voxels))
    throw std::invalid_argument("tsdf truncation must be at least 1 voxel");
  if (!(max_weight >= 1e-6) || !std::isfinite(max_weight))
    throw std::invalid_argument("tsdf max_weight must be a finite value >= 1e-6");
  if (!(min_range >= 0.0) || !(max_range > min_range) || !std::isfinite(max_range))
    throw std::invalid_argument("tsdf ranges must satisfy 0 <= min_range < max_range");
  if (max_points < 1) throw std::invalid_argument("tsdf max_points must be >= 1");
  if (threads < 1 || threads > 64) throw std::invalid_argument("tsdf threads must be in 1..64");
  if (remove_outliers) outliers.validate();
}

TsdfIntegrator::TsdfIntegrator(const TsdfIntegratorParams& params) : params_(params) {
  params_.validate();
}

IntegrationReport TsdfIntegrator::integrate(TsdfMap& map, const PointList& points,
                                            const Eigen::Isometry3d& sensor_pose) const {
  return integrateImpl(map, points, sensor_pose.translation(), &sensor_pose);
}

IntegrationReport TsdfIntegrator::integrate(TsdfMap& map, const PointList& points,
                                            const Eigen::Vector3d& origin) const {
  return integrateImpl(map, points, origin, nullptr);
}

IntegrationReport TsdfIntegrator::integrateImpl(TsdfMap& map, const PointList& points,
                                                const Eigen::Vector3d& origin,
                                                const Eigen::Isometry3d* pose) const {
  const auto start = std::chrono::steady_clock::now();
  IntegrationReport report;
  report.points_in = points.size();
  auto done = [&]() {
    report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return report;
  };
  if (!origin.allFinite() || (pose != nullptr && !pose->matrix().allFinite())) {
    report.error = "sensor pose is not finite; view refused";
    return done();
  }
  if (points.empty()) {
    report.error = "empty cloud; nothing to integrate";
    return done();
  }
  if (points.size() > params_.max_points) {
    std::ostringstream os;
    os << "cloud of " << points.size() << " points exceeds max_points " << params_.max_points
       << "; view refused (downsample it first)";
    report.error = os.str();
    return done();
  }

  // Scratch buffers kept between calls: a full frame needs ~65 MB of them, and memory fresh
  // from the OS costs a page fault per 4 KiB (~1.4 us each here: ~20 ms a frame). Another
  // thread's call meanwhile uses its own, and so does a cloud larger than ~1.3 VGA frames
  // (up to max_points it would need ~400 MB, not worth keeping).
  constexpr std::size_t kKeepScratchUpTo = 400000;
  std::unique_lock<std::mutex> scratch_lock(scratch_.mutex, std::defer_lock);
  if (points.size() <= kKeepScratchUpTo) scratch_lock.try_lock();
  std::unique_ptr<Scratch> own_scratch;
  Scratch* ws;
  if (scratch_lock.owns_lock()) {
    if (!scratch_.data) scratch_.data = std::make_shared<Scratch>();
    ws = scratch_.data.get();
  } else {
    own_scratch = std::make_unique<Scratch>();
    ws = own_scratch.get();
  }

  // Merge points per end-point voxel: mean position and count.
  const double vs = map.voxelSize();
  const double min_r2 = params_.min_range * params_.min_range;
  const double max_r2 = params_.max_range * params_.max_range;
  Eigen::Isometry3d to_sensor = Eigen::Isometry3d::Identity();
  if (pose != nullptr) to_sensor = pose->inverse();
  // First the voxel key of every point (kSkip: dropped), then the merge: a full frame's table
  // is far larger than the caches, so the slot of the point a few places ahead is prefetched.
  constexpr std::uint64_t kSkip = FlatHashMap<int>::kEmpty;
  const double inv_vs = 1.0 / vs;
  // floor() as an integer without a libm call (SSE2 has no rounding instruction), clamped far
  // beyond the 21 bits per axis a key keeps, so that no conversion overflows.
  auto floorToInt = [](double v) {
    v = std::min(4.0e15, std::max(-4.0e15, v));
    const std::int64_t c = static_cast<std::int64_t>(v);
    return c - (static_cast<double>(c) > v ? 1 : 0);
  };
  std::vector<std::uint64_t>& keys = ws->keys;
  keys.assign(points.size(), kSkip);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Point& p = points[i];
    if (!p.allFinite()) {
      ++report.non_finite;
      continue;
    }
    const double r2 = (p - origin).squaredNorm();
    if (r2 < min_r2 || r2 > max_r2 || (pose != nullptr && (to_sensor * p).z() <= params_.min_range)) {
      ++report.out_of_range;
      continue;
    }
    // The voxel key (only groups the points: a point on a voxel face may go either way).
    keys[i] = SpatialHashGrid::packKey(floorToInt(p.x() * inv_vs), floorToInt(p.y() * inv_vs), floorToInt(p.z() * inv_vs));
  }
  FlatHashMap<int>& slot = ws->slot;
  slot.reset(points.size());  // never grows: at most one entry per point
  std::vector<Scratch::Merged>& merged = ws->merged;
  merged.clear();
  constexpr std::size_t kAhead = 16;
  std::uint64_t last_key = kSkip;
  int last_slot = -1;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (i + kAhead < points.size() && keys[i + kAhead] != kSkip) slot.prefetch(keys[i + kAhead]);
    const std::uint64_t key = keys[i];
    if (key == kSkip) continue;
    // Clouds come in image order: neighbouring pixels often share a voxel, so the previous
    // point's slot saves most hash lookups of a close-up view.
    if (key != last_key) {
      const auto ins = slot.insert(key);
      if (ins.second) {
        *ins.first = static_cast<int>(merged.size());
        merged.emplace_back();
      }
      last_key = key;
      last_slot = *ins.first;
    }
    Scratch::Merged& m = merged[static_cast<std::size_t>(last_slot)];
    m.sum += points[i];
    ++m.count;
  }
  const auto merged_at = std::chrono::steady_clock::now();
  report.merge_seconds = std::chrono::duration<double>(merged_at - start).count();
  PointList& ends = ws->ends;
  ends.resize(merged.size());
  for (std::size_t i = 0; i < merged.size(); ++i) ends[i] = merged[i].sum / merged[i].count;

  // One neighbourhood pass over the merged end points gives both the outlier statistics and
  // the surface normals (PCA) for the incidence-limited band behind the surface.
  NeighbourhoodQuery query;
  query.radius = params_.remove_outliers ? params_.outliers.search_radius : 2.5 * vs;
  query.k = params_.remove_outliers ? params_.outliers.k : 0;
  query.normals = params_.incidence_limited_back_band;
  query.threads = ends.size() >= kParallelFrom ? params_.threads : 1;
  std::vector<double>& knn = ws->knn;
  std::vector<Eigen::Vector3d>& normals = ws->normals;
  analyseNeighbourhoods(ends, query, &knn, &normals, &ws->grid);
  const auto analysed_at = std::chrono::steady_clock::now();
  report.neighbourhood_seconds = std::chrono::duration<double>(analysed_at - merged_at).count();
  std::vector<char>& outlier = ws->outlier;
  outlier.assign(ends.size(), 0);
  if (params_.remove_outliers && ends.size() > static_cast<std::size_t>(params_.outliers.k)) {
    outlier = flagStatisticalOutliers(knn, params_.outliers.std_mul);
    report.outliers = std::count(outlier.begin(), outlier.end(), 1);
  }

  // The ray of merged point i: false if it has none (an outlier, or a point at the sensor).
  const double tau = params_.truncation_voxels * vs;
  struct Ray {
    Eigen::Vector3d dir;
    double range, weight, back_len;
  };
  auto rayOf = [&](std::size_t i, Ray* ray) {
    if (outlier[i]) return false;
    const Eigen::Vector3d& p = ends[i];
    ray->range = (p - origin).norm();
    if (!(ray->range > 0.0)) return false;  // a point at the sensor has no ray direction
    ray->dir = (p - origin) / ray->range;
    ray->weight = merged[i].count;
    // Behind the surface a grazing ray soon leaves a curved fruit again; the voxels it would
    // then mark as inside lie outside. Its band there is cut to tau * cos(incidence).
    ray->back_len = tau;
    if (query.normals && normals[i].allFinite()) ray->back_len = tau * std::max(0.25, std::abs(normals[i].dot(ray->dir)));
    if (params_.weighting == TsdfIntegratorParams::Weighting::kInverseSquare)
      ray->weight /= ray->range * ray->range;
    return true;
  };
  auto tally = [&](const BandCaster& c) {
    report.rays += c.rays;
    report.voxel_updates += c.voxel_updates;
    report.outside_map += c.partly_dropped_rays;
  };
  BandCaster caster(map, params_, tau);
  const std::size_t parts = static_cast<std::size_t>(params_.threads);
  if (parts < 2 || ends.size() < kParallelFrom || params_.carve_free_space) {
    Ray r;
    for (std::size_t i = 0; i < ends.size(); ++i)
      if (rayOf(i, &r)) caster.cast(ends[i], origin, r.dir, r.range, r.weight, r.back_len);
  } else {
    // In parallel: a ray whose band lies inside one block (~85 % of a full frame's: the band
    // is ~9 of a block's 64 voxels) goes to the thread owning that block; blocks are dealt out
    // by ray count, largest first. The rest, crossing block faces, follow on this thread.
    // Each voxel then sees its rays in the same order on every run, though not in the order
    // of the cloud (as with one thread): the map differs from that only by float rounding.
    const int nps = map.voxelsPerSide();
    // First, in parallel (pure arithmetic), the origin of the block whose inside holds each
    // ray's band, or none for rays that cross block faces or have no ray.
    std::vector<VoxelIndex>& ray_home = ws->ray_home;
    ray_home.resize(ends.size());
    const VoxelIndex kNone = VoxelIndex::Constant(std::numeric_limits<std::int64_t>::min());
    runParts(parts, [&](std::size_t t) {
      Ray tr;
      for (std::size_t i = ends.size() * t / parts, e = ends.size() * (t + 1) / parts; i < e; ++i) {
        ray_home[i] = kNone;
        if (!rayOf(i, &tr)) continue;
        VoxelIndex first, last;
        caster.bandVoxels(ends[i], origin, tr.dir, tr.range, tr.back_len, &first, &last);
        const VoxelIndex bo = map.blockOriginOf(first);
        const VoxelIndex lf = first - bo, ll = last - bo;
        // A voxel of margin: rounding may carry a traversal one voxel past `last`.
        if (lf.minCoeff() < 1 || ll.minCoeff() < 1 || lf.maxCoeff() > nps - 2 || ll.maxCoeff() > nps - 2) continue;
        ray_home[i] = bo;
      }
    });
    std::vector<int>& ray_block = ws->ray_block;  // index into `blocks`; -1: crossing or none
    ray_block.assign(ends.size(), -1);
    std::vector<TsdfBlock*> blocks;
    std::vector<VoxelIndex> block_origins;
    std::vector<std::size_t> block_rays;
    FlatHashMap<int> block_ids(256);
    TsdfBlock* last_block = nullptr;
    VoxelIndex last_home = kNone;
    int last_id = -1;
    Ray r;
    for (std::size_t i = 0; i < ends.size(); ++i) {
      if (ray_home[i] == kNone) continue;
      if (ray_home[i] == last_home && last_block != nullptr) {
        ray_block[i] = last_id;
        ++block_rays[static_cast<std::size_t>(last_id)];
        continue;
      }
      const VoxelIndex& bo = ray_home[i];
      TsdfBlock* block = map.blockForUpdate(bo);
      if (block == nullptr) continue;  // the serial pass counts what is dropped
      if (block != last_block) {
        const auto ins = block_ids.insert(reinterpret_cast<std::uintptr_t>(block));
        if (ins.second) {
          *ins.first = static_cast<int>(blocks.size());
          blocks.push_back(block);
          block_origins.push_back(bo);
          block_rays.push_back(0);
        }
        last_block = block;
        last_id = *ins.first;
      }
      last_home = ray_home[i];
      ray_block[i] = last_id;
      ++block_rays[static_cast<std::size_t>(last_id)];
    }
    std::vector<std::size_t> order(blocks.size()), load(parts, 0), owner(blocks.size());
    for (std::size_t b = 0; b < order.size(); ++b) order[b] = b;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
      return block_rays[a] != block_rays[b] ? block_rays[a] > block_rays[b] : a < b;
    });
    for (std::size_t b : order) {
      const std::size_t t = static_cast<std::size_t>(std::min_element(load.begin(), load.end()) - load.begin());
      owner[b] = t;
      load[t] += block_rays[b];
    }
    std::vector<std::unique_ptr<BandCaster>> casters(parts);
    runParts(parts, [&](std::size_t t) {
      casters[t] = std::make_unique<BandCaster>(map, params_, tau);
      BandCaster& c = *casters[t];
      Ray tr;
      for (std::size_t i = 0; i < ends.size(); ++i) {
        const int b = ray_block[i];
        if (b < 0 || owner[static_cast<std::size_t>(b)] != t || !rayOf(i, &tr)) continue;
        c.castWithin(blocks[static_cast<std::size_t>(b)], block_origins[static_cast<std::size_t>(b)], ends[i], origin,
                     tr.dir, tr.range, tr.weight, tr.back_len);
      }
      c.finish();
    });
    for (const auto& c : casters) tally(*c);
    for (std::size_t i = 0; i < ends.size(); ++i)
      if (ray_block[i] < 0 && rayOf(i, &r)) caster.cast(ends[i], origin, r.dir, r.range, r.weight, r.back_len);
  }
  caster.finish();
  tally(caster);

  report.ray_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - analysed_at).count();

  std::ostringstream warn;
  if (report.non_finite) warn << report.non_finite << " NaN/Inf points skipped; ";
  if (report.out_of_range) warn << report.out_of_range << " points outside the range limits skipped; ";
  if (report.outside_map)
    warn << report.outside_map << " rays partly outside the crop box or the block limit; ";
  report.warning = warn.str();
  if (!report.warning.empty()) report.warning.resize(report.warning.size() - 2);
  return done();
}

}  // namespace fruit_shape_completion
