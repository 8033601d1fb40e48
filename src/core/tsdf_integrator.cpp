#include <fruit_shape_completion/spatial_hash_grid.h>
#include <fruit_shape_completion/tsdf_integrator.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <exception>
#include <thread>

namespace fruit_shape_completion {

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

  // Merge points per end-point voxel: mean position and count.
  const double vs = map.voxelSize();
  struct Merged {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int count = 0;
  };
  FlatHashMap<int> slot(points.size() / 4 + 16);
  std::vector<Merged> merged;
  merged.reserve(points.size() / 4 + 16);
  const double min_r2 = params_.min_range * params_.min_range;
  const double max_r2 = params_.max_range * params_.max_range;
  Eigen::Isometry3d to_sensor = Eigen::Isometry3d::Identity();
  if (pose != nullptr) to_sensor = pose->inverse();
  std::uint64_t last_key = ~0ull;
  int last_slot = -1;
  for (const auto& p : points) {
    if (!p.allFinite()) {
      ++report.non_finite;
      continue;
    }
    const double r2 = (p - origin).squaredNorm();
    if (r2 < min_r2 || r2 > max_r2 || (pose != nullptr && (to_sensor * p).z() <= params_.min_range)) {
      ++report.out_of_range;
      continue;
    }
    const VoxelIndex v = map.voxelIndexOf(p);
    const auto key = SpatialHashGrid::packKey(v.x(), v.y(), v.z());
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
    Merged& m = merged[static_cast<std::size_t>(last_slot)];
    m.sum += p;
    ++m.count;
  }
  PointList ends(merged.size());
  for (std::size_t i = 0; i < merged.size(); ++i) ends[i] = merged[i].sum / merged[i].count;

  // One neighbourhood pass over the merged end points gives both the outlier statistics and
  // the surface normals (PCA) for the incidence-limited band behind the surface.
  const double radius = params_.remove_outliers ? params_.outliers.search_radius : 2.5 * vs;
  const bool analyse = params_.remove_outliers || params_.incidence_limited_back_band;
  const SpatialHashGrid grid(analyse ? ends : PointList(), radius);
  std::vector<double> knn(ends.size(), radius);
  std::vector<Eigen::Vector3d> normals(ends.size(), Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  // Cell by cell: the 27 neighbour cells are looked up once per cell and copied into flat
  // arrays, then every point of the cell tests them in one tight loop. Read-only over the grid,
  // one output slot per point: the cells are split over `threads` threads.
  const double r2 = radius * radius;
  auto analyseCells = [&](std::size_t first, std::size_t last) {
    std::vector<double> d2, cx, cy, cz, dist;
    std::vector<int> sel;
    grid.forEachCell(first, last, [&](const SpatialHashGrid::Cell& cell, const std::pair<int, int>* ranges, int nr) {
      cx.clear();
      cy.clear();
      cz.clear();
      for (int r = 0; r < nr; ++r)
        for (int k = ranges[r].first; k < ranges[r].second; ++k) {
          const Point& q = grid.storedPoint(k);
          cx.push_back(q.x());
          cy.push_back(q.y());
          cz.push_back(q.z());
        }
      const std::size_t nc = cx.size();
      dist.resize(nc);
      sel.resize(nc + 1);
      for (int k = cell.begin; k < cell.end; ++k) {
        const Point& p = grid.storedPoint(k);
        const std::size_t i = static_cast<std::size_t>(grid.originalIndex(k));
        const double px = p.x(), py = p.y(), pz = p.z();
        for (std::size_t j = 0; j < nc; ++j) {
          const double dx = cx[j] - px, dy = cy[j] - py, dz = cz[j] - pz;
          dist[j] = dx * dx + dy * dy + dz * dz;
        }
        // Branch-free compaction of the neighbours: most candidates fail the test, and a
        // branch per candidate would mispredict often.
        std::size_t n_sel = 0;
        for (std::size_t j = 0; j < nc; ++j) {
          sel[n_sel] = static_cast<int>(j);
          n_sel += dist[j] <= r2 ? 1 : 0;
        }
        d2.clear();
        double sx = 0, sy = 0, sz = 0, xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
        bool self_seen = false;
        for (std::size_t s = 0; s < n_sel; ++s) {
          const std::size_t j = static_cast<std::size_t>(sel[s]);
          if (!self_seen && dist[j] == 0.0) {
            self_seen = true;  // the point itself (contributes nothing to the sums)
            continue;
          }
          d2.push_back(dist[j]);
          const double dx = cx[j] - px, dy = cy[j] - py, dz = cz[j] - pz;
          sx += dx;
          sy += dy;
          sz += dz;
          xx += dx * dx;
          xy += dx * dy;
          xz += dx * dz;
          yy += dy * dy;
          yz += dy * dz;
          zz += dz * dz;
        }
        const double count = static_cast<double>(d2.size() + 1);
        if (params_.incidence_limited_back_band && count >= 5) {
          const Eigen::Vector3d mean = Eigen::Vector3d(sx, sy, sz) / count;
          Eigen::Matrix3d cov;
          cov << xx, xy, xz, xy, yy, yz, xz, yz, zz;
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
          es.computeDirect(cov - count * mean * mean.transpose());
          if (es.eigenvalues()(1) > 0.05 * es.eigenvalues()(2)) normals[i] = es.eigenvectors().col(0);
        }
        if (params_.remove_outliers) knn[i] = meanKnnDistance(d2, params_.outliers.k, radius);
      }
    });
  };
  if (analyse) {
    const std::size_t cells = grid.cells().size();
    const std::size_t parts = ends.size() >= 20000 ? static_cast<std::size_t>(params_.threads) : 1;
    // Nothing may escape a part before every thread is joined: each part keeps its exception,
    // the first one is rethrown afterwards (as the single-threaded pass would throw it).
    std::vector<std::exception_ptr> errors(parts);
    auto part = [&](std::size_t t) {
      try {
        analyseCells(cells * t / parts, cells * (t + 1) / parts);
      } catch (...) {
        errors[t] = std::current_exception();
      }
    };
    std::vector<std::thread> pool;
    for (std::size_t t = 1; t < parts; ++t) {
      try {
        pool.emplace_back(part, t);
      } catch (...) {  // no thread to be had: do it here
        part(t);
      }
    }
    part(0);
    for (auto& th : pool) th.join();
    for (const auto& e : errors)
      if (e) std::rethrow_exception(e);
  }
  std::vector<char> outlier(ends.size(), 0);
  if (params_.remove_outliers && ends.size() > static_cast<std::size_t>(params_.outliers.k)) {
    outlier = flagStatisticalOutliers(knn, params_.outliers.std_mul);
    report.outliers = std::count(outlier.begin(), outlier.end(), 1);
  }

  const double tau = params_.truncation_voxels * vs;
  const std::int64_t nps = map.voxelsPerSide();
  std::vector<TsdfBlock*> touched;  // blocks whose new observations get merged in at the end
  const bool crop = map.params().use_crop_box;
  const double inv_vs = 1.0 / vs;
  for (std::size_t i = 0; i < ends.size(); ++i) {
    if (outlier[i]) continue;
    const Eigen::Vector3d& p = ends[i];
    const double range = (p - origin).norm();
    if (!(range > 0.0)) continue;  // a point at the sensor has no ray direction
    const Eigen::Vector3d dir = (p - origin) / range;
    double w_ray = merged[i].count;
    // Behind the surface a grazing ray soon leaves a curved fruit again; the voxels it would
    // then mark as inside lie outside. Its band there is cut to tau * cos(incidence).
    double back_len = tau;
    if (normals[i].allFinite())
      back_len = tau * std::max(0.25, std::abs(normals[i].dot(dir)));
    if (params_.weighting == TsdfIntegratorParams::Weighting::kInverseSquare) w_ray /= range * range;
    const Eigen::Vector3d s = params_.carve_free_space ? origin : Eigen::Vector3d(p - dir * std::min(tau, range));
    const Eigen::Vector3d e = p + dir * back_len;
    ++report.rays;

    // Amanatides-Woo traversal of the voxels from s to e. The block, the index inside it and
    // the projective distance are carried along incrementally; a block is looked up only when
    // the ray crosses into the next one.
    const Eigen::Vector3d a = s * inv_vs, b = e * inv_vs, d = b - a;
    VoxelIndex cur = a.array().floor().cast<std::int64_t>();
    const VoxelIndex last = b.array().floor().cast<std::int64_t>();
    Eigen::Vector3d t_max, t_delta;
    std::int64_t step[3];
    for (int k = 0; k < 3; ++k) {
      step[k] = d[k] > 0 ? 1 : (d[k] < 0 ? -1 : 0);
      if (step[k] == 0) {
        t_max[k] = t_delta[k] = std::numeric_limits<double>::infinity();
      } else {
        const double boundary = static_cast<double>(cur[k] + (step[k] > 0 ? 1 : 0));
        t_max[k] = (boundary - a[k]) / d[k];
        t_delta[k] = std::abs(1.0 / d[k]);
      }
    }
    const std::int64_t stride[3] = {1, nps, nps * nps};
    VoxelIndex block_origin = map.blockOriginOf(cur);
    TsdfBlock* block = map.blockForUpdate(block_origin);
    if (block != nullptr && (touched.empty() || touched.back() != block)) touched.push_back(block);
    VoxelIndex local = cur - block_origin;
    std::int64_t idx = local.x() + nps * (local.y() + nps * local.z());
    double sdf = range - (map.voxelCenter(cur) - origin).dot(dir);  // projective distance
    const double sdf_step[3] = {vs * dir.x(), vs * dir.y(), vs * dir.z()};
    const std::int64_t max_steps = (last - cur).cwiseAbs().sum() + 1;
    bool dropped = false;
    for (std::int64_t n = 0; n <= max_steps; ++n) {
      if (sdf >= -back_len) {
        double w = w_ray;
        if (params_.drop_off && sdf < -vs) w *= (tau + sdf) / (tau - vs);
        if (w > 0.0) {
          if (block == nullptr || (crop && !map.insideCropBox(map.voxelCenter(cur)))) {
            dropped = true;
          } else {
            block->update(static_cast<std::uint32_t>(idx), std::min(sdf, tau), w, params_.max_weight);
            ++report.voxel_updates;
          }
        }
      }
      if (cur == last) break;
      int k = 0;
      if (t_max[1] < t_max[k]) k = 1;
      if (t_max[2] < t_max[k]) k = 2;
      if (t_max[k] > 1.0) break;
      cur[k] += step[k];
      t_max[k] += t_delta[k];
      sdf -= step[k] * sdf_step[k];
      local[k] += step[k];
      idx += step[k] * stride[k];
      if (local[k] < 0 || local[k] >= nps) {
        block_origin = map.blockOriginOf(cur);
        block = map.blockForUpdate(block_origin);
        if (block != nullptr && (touched.empty() || touched.back() != block)) touched.push_back(block);
        local = cur - block_origin;
        idx = local.x() + nps * (local.y() + nps * local.z());
      }
    }
    if (dropped) ++report.outside_map;
  }

  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  for (TsdfBlock* b : touched) b->sortObserved();

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
