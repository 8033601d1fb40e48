#include <fruit_shape_completion/neighbour_grid.h>
#include <fruit_shape_completion/surface_normals.h>
#include <fruit_shape_completion/tsdf_integrator.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace fruit_shape_completion {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// The slot of each voxel key of a view: open addressing with linear probing, sized once to at
// least 1.5 times the points so it never grows. A full frame's table is larger than the caches;
// the merge prefetches the slot of the point a few places ahead, which std::unordered_map's
// node chains do not allow (docs/benchmarks.md).
class VoxelSlots {
 public:
  static constexpr std::uint64_t kEmpty = ~std::uint64_t(0);  // packCellKey uses 63 bits

  explicit VoxelSlots(std::size_t max_entries) {
    std::size_t capacity = 16;
    while (2 * capacity < 3 * max_entries) capacity *= 2, --shift_;
    mask_ = capacity - 1;
    entries_.assign(capacity, Entry{kEmpty, 0});
  }
  void prefetch(std::uint64_t key) const { __builtin_prefetch(&entries_[home(key)]); }
  // The slot stored for `key`, or `fresh` (then stored) if the key is new.
  std::uint32_t findOrInsert(std::uint64_t key, std::uint32_t fresh) {
    for (std::size_t i = home(key);; i = (i + 1) & mask_) {
      Entry& e = entries_[i];
      if (e.key == key) return e.slot;
      if (e.key == kEmpty) {
        e = Entry{key, fresh};
        return fresh;
      }
    }
  }

 private:
  // Fibonacci hashing: the top bits of the product depend on every bit of the key.
  std::size_t home(std::uint64_t key) const { return (key * 0x9E3779B97F4A7C15ull) >> shift_; }
  int shift_ = 60;  // 64 - log2(capacity)
  std::size_t mask_ = 0;
  struct Entry {
    std::uint64_t key;
    std::uint32_t slot;
  };
  std::vector<Entry> entries_;
};

// One ray per end-point voxel: the mean of the view's points in it, weighted by their count.
struct MergedView {
  PointList ends;
  std::vector<double> counts;
};

MergedView mergePerVoxel(const PointList& points, const Eigen::Vector3d& origin, const Eigen::Isometry3d* pose,
                         const TsdfIntegratorParams& params, double voxel_size, IntegrationReport* report) {
  const double min_r2 = params.min_range * params.min_range;
  const double max_r2 = params.max_range * params.max_range;
  const Eigen::Isometry3d to_sensor = pose != nullptr ? pose->inverse() : Eigen::Isometry3d::Identity();
  const double inv_vs = 1.0 / voxel_size;
  // The key of every point first (kEmpty: dropped), so the merge can prefetch ahead.
  std::vector<std::uint64_t> keys(points.size(), VoxelSlots::kEmpty);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Point& p = points[i];
    if (!p.allFinite()) {
      ++report->non_finite;
      continue;
    }
    const double r2 = (p - origin).squaredNorm();
    if (r2 < min_r2 || r2 > max_r2 || (pose != nullptr && (to_sensor * p).z() <= params.min_range)) {
      ++report->out_of_range;
      continue;
    }
    keys[i] = packCellKey(cellOf(p, inv_vs));
  }
  MergedView view;
  VoxelSlots slots(points.size());
  constexpr std::size_t kAhead = 16;
  std::uint64_t last_key = VoxelSlots::kEmpty;
  std::uint32_t slot = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (i + kAhead < points.size() && keys[i + kAhead] != VoxelSlots::kEmpty) slots.prefetch(keys[i + kAhead]);
    const std::uint64_t key = keys[i];
    if (key == VoxelSlots::kEmpty) continue;
    // Clouds come in image order: neighbouring pixels often share a voxel.
    if (key != last_key) {
      slot = slots.findOrInsert(key, static_cast<std::uint32_t>(view.ends.size()));
      if (slot == view.ends.size()) {
        view.ends.push_back(Eigen::Vector3d::Zero());
        view.counts.push_back(0.0);
      }
      last_key = key;
    }
    view.ends[slot] += points[i];
    view.counts[slot] += 1.0;
  }
  for (std::size_t i = 0; i < view.ends.size(); ++i) view.ends[i] /= view.counts[i];
  return view;
}

// One neighbourhood pass over the merged end points gives both the outlier flags and the
// normals of the incidence-limited band (NaN where a point has none). Both relations are
// symmetric, so each close pair is measured once and counted for both points.
void analyseNeighbourhoods(const PointList& ends, const TsdfIntegratorParams& params, double voxel_size,
                           std::vector<char>* outlier, std::vector<Eigen::Vector3d>* normals) {
  const bool find_outliers = params.remove_outliers && ends.size() > static_cast<std::size_t>(params.outliers.k);
  const bool find_normals = params.incidence_limited_back_band;
  if (!find_outliers && !find_normals) return;
  NormalParams np;
  np.radius = 2.5 * voxel_size;
  const double outlier_r2 = params.outliers.search_radius * params.outliers.search_radius;
  const double normal_r2 = np.radius * np.radius;
  const double radius = std::max(find_outliers ? params.outliers.search_radius : 0.0, find_normals ? np.radius : 0.0);
  // Per-point state is kept in the grid's cell order, where the two points of a close pair
  // usually lie near each other in memory.
  const NeighbourGrid grid(ends, radius);
  const std::size_t n = grid.size();
  NearestDistances nearest(find_outliers ? n : 0, params.outliers);
  std::vector<NeighbourMoments> moments(find_normals ? n : 0);
  for (NeighbourMoments& m : moments) m.add(Eigen::Vector3d::Zero());  // the point itself
  grid.forEachPairByPosition(radius, [&](int i, int j, double dd) {
    const auto a = static_cast<std::size_t>(i), b = static_cast<std::size_t>(j);
    if (find_outliers && dd <= outlier_r2) {
      nearest.add(a, dd);
      nearest.add(b, dd);
    }
    if (find_normals && dd <= normal_r2) {
      const Eigen::Vector3d offset = grid.pointAt(b) - grid.pointAt(a);
      moments[a].add(offset);
      moments[b].add(-offset);
    }
  });
  if (find_outliers) {
    std::vector<double> statistic(ends.size(), std::numeric_limits<double>::quiet_NaN());
    for (std::size_t k = 0; k < n; ++k) statistic[static_cast<std::size_t>(grid.indexAt(k))] = nearest.meanDistance(k);
    *outlier = flagOutliers(statistic, params.outliers);
  }
  if (find_normals) {
    normals->assign(ends.size(), Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
    for (std::size_t k = 0; k < n; ++k) (*normals)[static_cast<std::size_t>(grid.indexAt(k))] = moments[k].normal(np);
  }
}

// Casts rays into the map: each updates the voxels it crosses within its band (from `tau`
// before the end point, or from the sensor with carve_free_space, to `back_len` behind it).
//
// The band voxels of a large view mostly miss the caches; a ray that applied its updates as it
// went would wait on each miss in turn. So the traversal queues the updates and prefetches their
// voxels, and the queue is applied in order: the misses overlap, the result is the same.
class BandCaster {
 public:
  BandCaster(TsdfMap& map, const TsdfIntegratorParams& params, double tau)
      : map_(map), params_(params), tau_(tau), vs_(map.voxelSize()), inv_vs_(1.0 / map.voxelSize()),
        inv_drop_len_(1.0 / (tau - map.voxelSize())), side_(map.voxelsPerSide()) {}
  ~BandCaster() { flush(); }

  std::size_t voxel_updates = 0;

  // Why part of a ray's band was dropped (a bitmask; 0: nothing was).
  enum Dropped : unsigned { kOutside = 1, kOverBudget = 2 };
  unsigned cast(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double range,
            double weight, double back_len);

 private:
  struct QueuedUpdate {
    TsdfBlock* block;
    std::uint32_t idx;
    float sdf;
    double weight;
  };
  static constexpr std::size_t kFlushAt = 1024;

  void flush() {
    for (const QueuedUpdate& u : queue_) u.block->update(u.idx, u.sdf, u.weight, params_.max_weight);
    queue_.clear();
  }
  // The weight of an update at signed distance sdf (0: none).
  double weightAt(double sdf, double ray_weight) const {
    if (params_.drop_off && sdf < -vs_) return ray_weight * (tau_ + sdf) * inv_drop_len_;
    return ray_weight;
  }
  // Why the map gave no block at `block_origin`: the budget, or the key range or crop box.
  unsigned missing(const VoxelIndex& block_origin) const {
    return map_.blockAllowed(block_origin) ? kOverBudget : kOutside;
  }
  // Queues the update of voxel (x, y, z) of `block` (block-local); 0, or why it is dropped
  // (`miss`, when there is no block).
  unsigned queue(TsdfBlock* block, unsigned miss, int x, int y, int z, double sdf, double weight) {
    if (block == nullptr) return miss;
    if (map_.params().use_crop_box && !map_.insideCropBox(map_.voxelCenter(block->origin + VoxelIndex(x, y, z))))
      return kOutside;
    const std::uint32_t idx = block->indexOf(x, y, z);
    __builtin_prefetch(&block->voxels[idx], 1);
    queue_.push_back({block, idx, std::min(static_cast<float>(sdf), static_cast<float>(tau_)), weight});
    ++voxel_updates;
    return 0;
  }

  TsdfMap& map_;
  const TsdfIntegratorParams& params_;
  const double tau_, vs_, inv_vs_, inv_drop_len_;
  const int side_;
  std::vector<QueuedUpdate> queue_;
};

unsigned BandCaster::cast(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                      double range, double weight, double back_len) {
  // Amanatides-Woo traversal from a to b in voxel units, in block-local coordinates; the block
  // is looked up only when the ray crosses into the next one. The loop carries scalars only:
  // per-axis arrays indexed by the step axis would go through the stack at every step.
  const Eigen::Vector3d start = params_.carve_free_space ? origin : Eigen::Vector3d(p - dir * std::min(tau_, range));
  const Eigen::Vector3d end = p + dir * back_len;
  const Eigen::Vector3d a = start * inv_vs_, d = end * inv_vs_ - a;
  const VoxelIndex first = cellOf(start, inv_vs_), last = cellOf(end, inv_vs_);
  const double inf = std::numeric_limits<double>::infinity();
  auto setup = [&](int k, int& step, double& t_max, double& t_delta) {
    step = d[k] > 0 ? 1 : (d[k] < 0 ? -1 : 0);
    t_max = t_delta = inf;
    if (step != 0) {
      t_max = (static_cast<double>(first[k] + (step > 0 ? 1 : 0)) - a[k]) / d[k];
      t_delta = std::abs(1.0 / d[k]);
    }
  };
  int sx, sy, sz;
  double tx, ty, tz, dtx, dty, dtz;
  setup(0, sx, tx, dtx);
  setup(1, sy, ty, dty);
  setup(2, sz, tz, dtz);
  VoxelIndex block_origin = map_.blockOriginOf(first);
  TsdfBlock* block = map_.blockForUpdate(block_origin);
  unsigned miss = block == nullptr ? missing(block_origin) : 0;
  int x = static_cast<int>(first.x() - block_origin.x());
  int y = static_cast<int>(first.y() - block_origin.y());
  int z = static_cast<int>(first.z() - block_origin.z());
  double sdf = range - (map_.voxelCenter(first) - origin).dot(dir);  // projective distance
  const double dsx = sx * vs_ * dir.x(), dsy = sy * vs_ * dir.y(), dsz = sz * vs_ * dir.z();
  const std::int64_t steps = (last - first).cwiseAbs().sum();
  unsigned dropped = 0;
  for (std::int64_t n = 0;; ++n) {
    const double w = sdf >= -back_len ? weightAt(sdf, weight) : 0.0;
    if (w > 0.0) dropped |= queue(block, miss, x, y, z, sdf, w);
    if (n == steps) break;
    int* moved;  // the axis whose boundary comes first (ties: x, then y, then z)
    if (tx <= ty && tx <= tz) {
      if (tx > 1.0) break;
      tx += dtx, sdf -= dsx, x += sx, moved = &x;
    } else if (ty <= tz) {
      if (ty > 1.0) break;
      ty += dty, sdf -= dsy, y += sy, moved = &y;
    } else {
      if (tz > 1.0) break;
      tz += dtz, sdf -= dsz, z += sz, moved = &z;
    }
    if (static_cast<unsigned>(*moved) >= static_cast<unsigned>(side_)) {
      const VoxelIndex voxel = block_origin + VoxelIndex(x, y, z);
      block_origin = map_.blockOriginOf(voxel);
      block = map_.blockForUpdate(block_origin);
      miss = block == nullptr ? missing(block_origin) : 0;
      x = static_cast<int>(voxel.x() - block_origin.x());
      y = static_cast<int>(voxel.y() - block_origin.y());
      z = static_cast<int>(voxel.z() - block_origin.z());
    }
  }
  if (queue_.size() >= kFlushAt) flush();
  return dropped;
}

}  // namespace

void TsdfIntegratorParams::validate() const {
  if (!(truncation_voxels >= 1.0) || !std::isfinite(truncation_voxels))
    throw std::invalid_argument("tsdf truncation must be at least 1 voxel");
  if (!(max_weight >= 1e-6) || !std::isfinite(max_weight))
    throw std::invalid_argument("tsdf max_weight must be a finite value >= 1e-6");
  // Bounded: carving free space steps through every voxel of a ray.
  if (!(min_range >= 0.0) || !(max_range > min_range) || !(max_range <= 100.0))
    throw std::invalid_argument("tsdf ranges must satisfy 0 <= min_range < max_range <= 100 m");
  if (max_points < 1) throw std::invalid_argument("tsdf max_points must be >= 1");
  if (remove_outliers) outliers.validate();
}

TsdfIntegrator::TsdfIntegrator(const TsdfIntegratorParams& params) : params_(params) { params_.validate(); }

IntegrationReport TsdfIntegrator::integrate(TsdfMap& map, const PointList& points,
                                            const Eigen::Isometry3d& sensor_pose) const {
  return integrateImpl(map, points, sensor_pose.translation(), &sensor_pose);
}

IntegrationReport TsdfIntegrator::integrate(TsdfMap& map, const PointList& points,
                                            const Eigen::Vector3d& origin) const {
  return integrateImpl(map, points, origin, nullptr);
}

IntegrationReport TsdfIntegrator::integrateImpl(TsdfMap& map, const PointList& points, const Eigen::Vector3d& origin,
                                                const Eigen::Isometry3d* pose) const {
  const auto start = Clock::now();
  IntegrationReport report;
  report.points_in = points.size();
  if (!origin.allFinite() || (pose != nullptr && !pose->matrix().allFinite())) {
    report.error = "sensor pose is not finite; view refused";
  } else if (origin.cwiseAbs().maxCoeff() > kMaxCoordinate) {
    report.error = "sensor position beyond 1e4 m; view refused";
  } else if (points.empty()) {
    report.error = "empty cloud; nothing to integrate";
  } else if (points.size() > params_.max_points) {
    std::ostringstream os;
    os << "cloud of " << points.size() << " points exceeds max_points " << params_.max_points
       << "; view refused (downsample it first)";
    report.error = os.str();
  }
  if (!report.ok()) {
    report.seconds = secondsSince(start);
    return report;
  }

  const double vs = map.voxelSize();
  const MergedView view = mergePerVoxel(points, origin, pose, params_, vs, &report);
  report.merge_seconds = secondsSince(start);

  const auto neighbourhood_start = Clock::now();
  std::vector<char> outlier(view.ends.size(), 0);
  std::vector<Eigen::Vector3d> normals;
  analyseNeighbourhoods(view.ends, params_, vs, &outlier, &normals);
  report.outliers = static_cast<std::size_t>(std::count(outlier.begin(), outlier.end(), 1));
  report.neighbourhood_seconds = secondsSince(neighbourhood_start);

  const auto ray_start = Clock::now();
  const double tau = params_.truncation_voxels * vs;
  {
    BandCaster caster(map, params_, tau);
    for (std::size_t i = 0; i < view.ends.size(); ++i) {
      const Eigen::Vector3d& p = view.ends[i];
      const double range = (p - origin).norm();
      if (outlier[i]) continue;
      if (!(range > 0.0)) {  // points at the sensor have no ray direction (possible with min_range 0)
        report.out_of_range += static_cast<std::size_t>(view.counts[i]);
        continue;
      }
      const Eigen::Vector3d dir = (p - origin) / range;
      // Behind the surface a grazing ray soon leaves a curved fruit again; the voxels it would
      // then mark as inside lie outside. Its band there is cut to tau * cos(incidence).
      double back_len = tau;
      if (!normals.empty() && normals[i].allFinite()) back_len = tau * std::max(0.25, std::abs(normals[i].dot(dir)));
      double weight = view.counts[i];
      if (params_.weighting == TsdfIntegratorParams::Weighting::kInverseSquare) weight /= range * range;
      ++report.rays;
      const unsigned dropped = caster.cast(p, origin, dir, range, weight, back_len);
      if (dropped & BandCaster::kOutside) ++report.outside_map;
      if (dropped & BandCaster::kOverBudget) ++report.over_budget;
    }
    report.voxel_updates = caster.voxel_updates;
  }
  report.ray_seconds = secondsSince(ray_start);

  std::ostringstream warn;
  if (report.non_finite) warn << report.non_finite << " NaN/Inf points skipped; ";
  if (report.out_of_range) warn << report.out_of_range << " points outside the range limits skipped; ";
  if (report.outside_map) warn << report.outside_map << " rays partly outside the crop box or the map's range; ";
  if (report.over_budget)
    warn << report.over_budget << " rays partly dropped: the map is at its memory budget (" << map.blockCount()
         << " blocks, memory_budget_mb " << map.params().memory_budget_mb << "); ";
  report.warning = warn.str();
  if (!report.warning.empty()) report.warning.resize(report.warning.size() - 2);
  report.seconds = secondsSince(start);
  return report;
}

}  // namespace fruit_shape_completion
