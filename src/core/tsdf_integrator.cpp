#include <fruit_shape_completion/surface_normals.h>
#include <fruit_shape_completion/tsdf_integrator.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

namespace fruit_shape_completion {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

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
  MergedView view;
  std::unordered_map<std::uint64_t, std::size_t> slot;
  slot.reserve(points.size() / 4 + 16);
  std::uint64_t last_key = 0;
  std::size_t last_slot = std::numeric_limits<std::size_t>::max();
  for (const Point& p : points) {
    if (!p.allFinite()) {
      ++report->non_finite;
      continue;
    }
    const double r2 = (p - origin).squaredNorm();
    if (r2 < min_r2 || r2 > max_r2 || (pose != nullptr && (to_sensor * p).z() <= params.min_range)) {
      ++report->out_of_range;
      continue;
    }
    // Clouds come in image order: neighbouring pixels often share a voxel.
    const std::uint64_t key = packCellKey(cellOf(p, inv_vs));
    if (key != last_key || last_slot == std::numeric_limits<std::size_t>::max()) {
      const auto ins = slot.emplace(key, view.ends.size());
      if (ins.second) {
        view.ends.push_back(Eigen::Vector3d::Zero());
        view.counts.push_back(0.0);
      }
      last_key = key;
      last_slot = ins.first->second;
    }
    view.ends[last_slot] += p;
    view.counts[last_slot] += 1.0;
  }
  for (std::size_t i = 0; i < view.ends.size(); ++i) view.ends[i] /= view.counts[i];
  return view;
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
        side_(map.voxelsPerSide()) {}
  ~BandCaster() { flush(); }

  std::size_t voxel_updates = 0;

  // True if part of the ray's band was dropped (outside the crop box or the block limit).
  bool cast(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double range,
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
    if (params_.drop_off && sdf < -vs_) return ray_weight * (tau_ + sdf) / (tau_ - vs_);
    return ray_weight;
  }

  TsdfMap& map_;
  const TsdfIntegratorParams& params_;
  const double tau_, vs_, inv_vs_;
  const int side_;
  std::vector<QueuedUpdate> queue_;
};

bool BandCaster::cast(const Eigen::Vector3d& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                      double range, double weight, double back_len) {
  // Amanatides-Woo traversal from a to b in voxel units; the block is looked up only when the
  // ray crosses into the next one.
  const Eigen::Vector3d start = params_.carve_free_space ? origin : Eigen::Vector3d(p - dir * std::min(tau_, range));
  const Eigen::Vector3d a = start * inv_vs_, b = (p + dir * back_len) * inv_vs_;
  const Eigen::Vector3d d = b - a;
  const VoxelIndex first = cellOf(start, inv_vs_), last = cellOf(p + dir * back_len, inv_vs_);
  Eigen::Vector3i step;
  Eigen::Vector3d t_max, t_delta;
  for (int k = 0; k < 3; ++k) {
    step[k] = d[k] > 0 ? 1 : (d[k] < 0 ? -1 : 0);
    if (step[k] == 0) {
      t_max[k] = t_delta[k] = std::numeric_limits<double>::infinity();
    } else {
      t_max[k] = (static_cast<double>(first[k] + (step[k] > 0 ? 1 : 0)) - a[k]) / d[k];
      t_delta[k] = std::abs(1.0 / d[k]);
    }
  }
  VoxelIndex voxel = first;
  VoxelIndex block_origin = map_.blockOriginOf(voxel);
  TsdfBlock* block = map_.blockForUpdate(block_origin);
  double sdf = range - (map_.voxelCenter(first) - origin).dot(dir);  // projective distance
  const std::int64_t steps = (last - first).cwiseAbs().sum();
  const float sdf_max = static_cast<float>(tau_);
  bool dropped = false;
  for (std::int64_t n = 0;; ++n) {
    const double w = sdf >= -back_len ? weightAt(sdf, weight) : 0.0;
    if (w > 0.0) {
      if (block == nullptr || (map_.params().use_crop_box && !map_.insideCropBox(map_.voxelCenter(voxel)))) {
        dropped = true;
      } else {
        const VoxelIndex l = voxel - block_origin;
        const std::uint32_t idx = block->indexOf(static_cast<int>(l.x()), static_cast<int>(l.y()), static_cast<int>(l.z()));
        __builtin_prefetch(&block->voxels[idx], 1);
        queue_.push_back({block, idx, std::min(static_cast<float>(sdf), sdf_max), w});
        ++voxel_updates;
      }
    }
    if (n == steps) break;
    int k;  // the axis whose boundary comes first
    t_max.minCoeff(&k);
    if (t_max[k] > 1.0) break;
    t_max[k] += t_delta[k];
    voxel[k] += step[k];
    sdf -= step[k] * vs_ * dir[k];
    const VoxelIndex l = voxel - block_origin;
    if (l[k] < 0 || l[k] >= side_) {
      block_origin = map_.blockOriginOf(voxel);
      block = map_.blockForUpdate(block_origin);
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
  if (!(min_range >= 0.0) || !(max_range > min_range) || !std::isfinite(max_range))
    throw std::invalid_argument("tsdf ranges must satisfy 0 <= min_range < max_range");
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
  if (params_.remove_outliers && view.ends.size() > static_cast<std::size_t>(params_.outliers.k)) {
    outlier = findStatisticalOutliers(view.ends, params_.outliers);
    report.outliers = static_cast<std::size_t>(std::count(outlier.begin(), outlier.end(), 1));
  }
  std::vector<Eigen::Vector3d> normals;
  if (params_.incidence_limited_back_band) {
    NormalParams np;
    np.radius = 2.5 * vs;
    np.max_points = 0;
    normals = estimateNormals(view.ends, np, origin).normals;
  }
  report.neighbourhood_seconds = secondsSince(neighbourhood_start);

  const auto ray_start = Clock::now();
  const double tau = params_.truncation_voxels * vs;
  {
    BandCaster caster(map, params_, tau);
    for (std::size_t i = 0; i < view.ends.size(); ++i) {
      const Eigen::Vector3d& p = view.ends[i];
      const double range = (p - origin).norm();
      if (outlier[i] || !(range > 0.0)) continue;  // a point at the sensor has no ray direction
      const Eigen::Vector3d dir = (p - origin) / range;
      // Behind the surface a grazing ray soon leaves a curved fruit again; the voxels it would
      // then mark as inside lie outside. Its band there is cut to tau * cos(incidence).
      double back_len = tau;
      if (!normals.empty() && normals[i].allFinite()) back_len = tau * std::max(0.25, std::abs(normals[i].dot(dir)));
      double weight = view.counts[i];
      if (params_.weighting == TsdfIntegratorParams::Weighting::kInverseSquare) weight /= range * range;
      ++report.rays;
      if (caster.cast(p, origin, dir, range, weight, back_len)) ++report.outside_map;
    }
    report.voxel_updates = caster.voxel_updates;
  }
  report.ray_seconds = secondsSince(ray_start);

  std::ostringstream warn;
  if (report.non_finite) warn << report.non_finite << " NaN/Inf points skipped; ";
  if (report.out_of_range) warn << report.out_of_range << " points outside the range limits skipped; ";
  if (report.outside_map) warn << report.outside_map << " rays partly outside the crop box or the block limit; ";
  report.warning = warn.str();
  if (!report.warning.empty()) report.warning.resize(report.warning.size() - 2);
  report.seconds = secondsSince(start);
  return report;
}

}  // namespace fruit_shape_completion
