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

  std::size_t voxel_updates = 0;

  // True if part of the ray's band was dropped (outside the crop box or the block limit).
  bool cast(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double range,
            double w_ray, double back_len) {
    return slab_axis_ < 0 ? walk<false>(p, origin, dir, range, w_ray, back_len)
                          : walk<true>(p, origin, dir, range, w_ray, back_len);
  }
  // From now on only the blocks whose origin along `axis` lies in [lo, hi) (voxel units) are
  // updated; the rest of each ray is walked but left alone (not counted as dropped). Blocks
  // are then looked up and created under `table_mutex`, so casters on disjoint slabs may run
  // concurrently.
  void keepToSlab(int axis, std::int64_t lo, std::int64_t hi, std::mutex* table_mutex) {
    slab_axis_ = axis;
    slab_lo_ = lo;
    slab_hi_ = hi;
    table_mutex_ = table_mutex;
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

  // kSlab: keepToSlab() is in force (one thread's pass compiles without its checks).
  template <bool kSlab>
  bool walk(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double range,
            double w_ray, double back_len);

  void flush() {
    const double max_weight = params_.max_weight;
    for (std::size_t k = 0; k < queued_; ++k) {
      const QueuedUpdate& u = queue_[k];
      u.block->update(u.idx, u.sdf, u.weight, max_weight);
    }
    queued_ = 0;
  }
  // The band's start and end in voxel units.
  void bandEnds(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double range,
                double back_len, Eigen::Vector3d* a, Eigen::Vector3d* b) const {
    const Eigen::Vector3d s = params_.carve_free_space ? origin : Eigen::Vector3d(p - dir * std::min(tau_, range));
    *a = s * inv_vs_;
    *b = (p + dir * back_len) * inv_vs_;
  }
  // The block holding `voxel` (its origin into *block_origin), or nullptr: refused by the map,
  // or (*foreign) outside this caster's slab.
  template <bool kSlab>
  TsdfBlock* enterBlock(const VoxelIndex& voxel, VoxelIndex* block_origin, bool* foreign) {
    *block_origin = map_.blockOriginOf(voxel);
    if (!kSlab) return map_.blockForUpdate(*block_origin);
    const std::int64_t c = (*block_origin)[slab_axis_];
    *foreign = c < slab_lo_ || c >= slab_hi_;
    if (*foreign) return nullptr;
    if (!slab_cached_ || *block_origin != slab_cached_origin_) {
      std::lock_guard<std::mutex> lock(*table_mutex_);
      slab_cached_block_ = map_.blockForUpdate(*block_origin);
      slab_cached_origin_ = *block_origin;
      slab_cached_ = true;
    }
    return slab_cached_block_;
  }

  TsdfMap& map_;
  const TsdfIntegratorParams& params_;
  const double tau_, vs_, inv_vs_;
  const int nps_;
  const std::uint32_t *layout_x_, *layout_y_, *layout_z_;
  const bool crop_;
  std::vector<QueuedUpdate> queue_;
  std::size_t queued_ = 0;
  // keepToSlab(); slab_axis_ < 0: no slab, blocks come from blockForUpdate (and its cache).
  int slab_axis_ = -1;
  std::int64_t slab_lo_ = 0, slab_hi_ = 0;
  std::mutex* table_mutex_ = nullptr;
  bool slab_cached_ = false;  // the last block looked up in the slab
  VoxelIndex slab_cached_origin_ = VoxelIndex::Zero();
  TsdfBlock* slab_cached_block_ = nullptr;
};

template <bool kSlab>
bool BandCaster::walk(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                      double range, double w_ray, double back_len) {
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
  bool foreign = false;
  TsdfBlock* block = enterBlock<kSlab>(first, &block_origin, &foreign);
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
        if (block == nullptr) {
          dropped = dropped || !(kSlab && foreign);  // another caster's slab is not dropped
        } else if (crop_ && !map_.insideCropBox(map_.voxelCenter(block_origin + VoxelIndex(lx, ly, lz)))) {
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
      const VoxelIndex voxel = block_origin + VoxelIndex(lx, ly, lz);
      block = enterBlock<kSlab>(voxel, &block_origin, &foreign);
      lx = static_cast<int>(voxel.x() - block_origin.x());
      ly = static_cast<int>(voxel.y() - block_origin.y());
      lz = static_cast<int>(voxel.z() - block_origin.z());
    }
  }
  const std::size_t added = static_cast<std::size_t>(out - (queue_.data() + queued_));
  queued_ += added;
  voxel_updates += added;
  if (queued_ >= kQueueFlush) flush();
  return dropped;
}

// Clouds of at least this many merged points are worth more than one thread.
constexpr std::size_t kParallelFrom = 20000;

// floor(v) as an integer without a libm call (SSE2 has no rounding instruction), clamped far
// beyond the 2^21 voxels or blocks a side that map keys keep, so that no conversion overflows.
inline std::int64_t floorToInt(double v) {
  v = std::min(4.0e15, std::max(-4.0e15, v));
  const std::int64_t c = static_cast<std::int64_t>(v);
  return c - (static_cast<double>(c) > v ? 1 : 0);
}

// The blocks along one axis a ray's band may reach, from its end point coordinate x on that
// axis: a band reaches at most tau from its end point, plus a voxel for rounding (`reach`).
// Monotone in x, so lo <= floor(x * inv_block) <= hi.
struct BandSpan {
  std::int64_t lo, hi;
  BandSpan(double x, double reach, double inv_block)
      : lo(floorToInt((x - reach) * inv_block)), hi(floorToInt((x + reach) * inv_block)) {}
};

// How the parallel ray pass cuts the map: slabs [bounds[t], bounds[t + 1]) in block units
// along `axis`, one per thread. A ray is cast by every slab its band may reach.
struct SlabCut {
  int axis = -1;  // -1: no cut worth having
  std::vector<std::int64_t> bounds;
  double new_blocks_bound = 0;  // blocks in the bounding box of all bands: at most this many are made
};

// Cuts at block faces along the axis where the busiest slab casts the fewest rays (a ray near
// a cut counts in both slabs), judged on every 4th ray: the least such load is found by
// bisection, each candidate checked by filling slabs greedily from one end.
SlabCut chooseSlabs(const PointList& ends, const std::vector<char>& outlier, double reach, double inv_block,
                    std::size_t parts) {
  constexpr std::int64_t kMaxSpan = 4096;  // blocks along an axis worth a histogram
  constexpr std::size_t kSample = 4;
  SlabCut best;
  Eigen::Vector3d lo_p = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi_p = -lo_p;
  std::size_t rays = 0;
  for (std::size_t i = 0; i < ends.size(); ++i)
    if (!outlier[i]) {
      lo_p = lo_p.cwiseMin(ends[i]);
      hi_p = hi_p.cwiseMax(ends[i]);
      rays += i % kSample == 0 ? 1 : 0;
    }
  if (rays == 0) return best;
  std::int64_t mins[3], maxs[3];
  best.new_blocks_bound = 1.0;
  for (int axis = 0; axis < 3; ++axis) {
    mins[axis] = BandSpan(lo_p[axis], reach, inv_block).lo;
    maxs[axis] = BandSpan(hi_p[axis], reach, inv_block).hi;
    best.new_blocks_bound *= static_cast<double>(maxs[axis] - mins[axis] + 1);
  }
  std::size_t best_load = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const std::int64_t mn = mins[axis], mx = maxs[axis];
    const std::int64_t span = mx - mn + 1;
    if (span < 2 || span > kMaxSpan) continue;
    // lo_below[c]: rays whose span starts before column c; hi_below[c]: ends before it. The rays
    // reaching into columns [s, e) are then lo_below[e] - hi_below[s].
    std::vector<std::size_t> lo_below(static_cast<std::size_t>(span) + 1, 0), hi_below(lo_below.size(), 0);
    for (std::size_t i = 0; i < ends.size(); i += kSample)
      if (!outlier[i]) {
        const BandSpan b(ends[i][axis], reach, inv_block);
        ++lo_below[static_cast<std::size_t>(b.lo - mn) + 1];
        ++hi_below[static_cast<std::size_t>(b.hi - mn) + 1];
      }
    for (std::size_t c = 1; c < lo_below.size(); ++c) {
      lo_below[c] += lo_below[c - 1];
      hi_below[c] += hi_below[c - 1];
    }
    const std::size_t columns = static_cast<std::size_t>(span);
    auto load = [&](std::size_t s, std::size_t e) { return lo_below[e] - hi_below[s]; };
    // The slab ends of a greedy fill with at most `limit` rays a slab (empty if it needs more
    // than `parts` slabs or one column alone exceeds it).
    auto fill = [&](std::size_t limit) {
      std::vector<std::size_t> slab_ends;
      for (std::size_t s = 0; s < columns;) {
        std::size_t e = s + 1;
        if (load(s, e) > limit || slab_ends.size() == parts) return std::vector<std::size_t>();
        while (e < columns && load(s, e + 1) <= limit) ++e;
        slab_ends.push_back(e);
        s = e;
      }
      return slab_ends;
    };
    std::size_t lo = 1, hi = rays;  // fill(hi) always succeeds: one slab takes every ray
    while (lo < hi) {
      const std::size_t mid = lo + (hi - lo) / 2;
      if (fill(mid).empty()) lo = mid + 1; else hi = mid;
    }
    const std::vector<std::size_t> slab_ends = fill(lo);
    // Worth it only if the busiest slab is clearly less than all of the view.
    if (slab_ends.size() < 2 || 4 * lo > 3 * rays || (best.axis >= 0 && lo >= best_load)) continue;
    best.axis = axis;
    best_load = lo;
    best.bounds.assign(1, std::numeric_limits<std::int64_t>::min());  // the outer slabs reach to the end
    for (std::size_t k = 0; k + 1 < slab_ends.size(); ++k)
      best.bounds.push_back(mn + static_cast<std::int64_t>(slab_ends[k]));
    best.bounds.push_back(std::numeric_limits<std::int64_t>::max());
  }
  return best;
}

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
  const std::size_t parts = static_cast<std::size_t>(params_.threads);
  bool serial = parts < 2 || ends.size() < kParallelFrom || params_.carve_free_space;
  if (!serial) {
    // In parallel: the map is cut at block faces into one slab per thread (chooseSlabs); each
    // thread casts the rays that may reach into its slab and updates only the voxels there (a
    // ray near a cut is walked by both). Every voxel thus sees its rays in the order of the
    // cloud, as with one thread: the same map, bit for bit.
    const double reach = tau + 1.5 * vs;
    const double inv_block = 1.0 / (vs * map.voxelsPerSide());
    const SlabCut cut = chooseSlabs(ends, outlier, reach, inv_block, parts);
    // Blocks made at once by several threads come in another order than one thread would make
    // them; that only matters if the map may reach max_blocks in this view. Then one thread.
    serial = cut.axis < 0 || static_cast<double>(map.blockCount()) + cut.new_blocks_bound > map.params().max_blocks;
    if (!serial) {
      const int axis = cut.axis;
      const std::int64_t nps = map.voxelsPerSide();
      const std::size_t slabs = cut.bounds.size() - 1;
      report.ray_threads = slabs;
      std::mutex table_mutex;
      std::vector<std::unique_ptr<BandCaster>> casters(slabs);
      std::vector<std::vector<std::size_t>> dropped(slabs);
      std::vector<std::size_t> rays(slabs, 0);
      runParts(slabs, [&](std::size_t s) {
        casters[s] = std::make_unique<BandCaster>(map, params_, tau);
        BandCaster& c = *casters[s];
        const std::int64_t lo = cut.bounds[s], hi = cut.bounds[s + 1];
        c.keepToSlab(axis, s == 0 ? std::numeric_limits<std::int64_t>::min() : lo * nps,
                     s + 1 == slabs ? std::numeric_limits<std::int64_t>::max() : hi * nps, &table_mutex);
        Ray tr;
        std::size_t home_rays = 0;  // kept here, not in rays[s]: threads writing one cache line stall
        std::vector<std::size_t> partly_dropped;
        for (std::size_t i = 0; i < ends.size(); ++i) {
          if (outlier[i]) continue;
          const double x = ends[i][axis];
          const BandSpan span(x, reach, inv_block);
          if (span.hi < lo || span.lo >= hi || !rayOf(i, &tr)) continue;
          // The ray counts in the slab of its end point (one of those that cast it).
          const std::int64_t home = floorToInt(x * inv_block);
          home_rays += (home >= lo || s == 0) && (home < hi || s + 1 == slabs) ? 1 : 0;
          if (c.cast(ends[i], origin, tr.dir, tr.range, tr.weight, tr.back_len)) partly_dropped.push_back(i);
        }
        c.finish();
        rays[s] = home_rays;
        dropped[s].swap(partly_dropped);
      });
      // A ray across a cut may have been dropped in part on either side: counted once.
      std::vector<std::size_t> all;
      for (std::size_t s = 0; s < slabs; ++s) {
        report.rays += rays[s];
        report.voxel_updates += casters[s]->voxel_updates;
        all.insert(all.end(), dropped[s].begin(), dropped[s].end());
      }
      std::sort(all.begin(), all.end());
      report.outside_map += static_cast<std::size_t>(std::unique(all.begin(), all.end()) - all.begin());
    }
  }
  if (serial) {
    BandCaster caster(map, params_, tau);
    Ray r;
    for (std::size_t i = 0; i < ends.size(); ++i)
      if (rayOf(i, &r)) {
        ++report.rays;
        if (caster.cast(ends[i], origin, r.dir, r.range, r.weight, r.back_len)) ++report.outside_map;
      }
    caster.finish();
    report.voxel_updates += caster.voxel_updates;
  }

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
