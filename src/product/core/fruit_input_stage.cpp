#include <fruit_shape_completion/fruit_input_stage.h>
#include <fruit_shape_completion/grid_cell.h>
#include <fruit_shape_completion/neighbour_grid.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <unordered_map>
#include <unordered_set>
#include <stdexcept>

namespace fruit_shape_completion {

std::string OrganizedFrame::problem() const {
  if (width <= 0 || height <= 0)
    return "frame is " + std::to_string(width) + " x " + std::to_string(height) + " pixels";
  if (width > 100000 || height > 100000 || pixels() > 50000000u)
    return "frame of " + std::to_string(width) + " x " + std::to_string(height) + " pixels is beyond any camera";
  if (xyz.size() != 3 * pixels())
    return "frame has " + std::to_string(xyz.size()) + " coordinates for " + std::to_string(pixels()) + " pixels";
  if (rgb.size() != 3 * pixels())
    return "frame has " + std::to_string(rgb.size()) + " colour bytes for " + std::to_string(pixels()) + " pixels";
  return {};
}

void FruitInputParams::validate() const {
  // An empty band would pass no pixel: every view would map nothing, with no other sign.
  if (red_test.min_hue > red_test.max_hue)
    throw std::invalid_argument("red_min_hue (" + std::to_string(red_test.min_hue) + ") must not exceed red_max_hue (" +
                                std::to_string(red_test.max_hue) + ")");
  depth_edges.validate();
  try {
    outliers.validate();
  } catch (const std::invalid_argument& e) {  // the map's integrator has an outlier filter of its own
    throw std::invalid_argument(std::string("input stage (input_outlier_k, input_outlier_std_mul, input_outlier_radius): ") +
                                e.what());
  }
  if (!(veil_radius > 0.0 && veil_radius <= 0.2)) throw std::invalid_argument("veil_radius must be in (0, 0.2] m");
  if (!(veil_angle_deg > 0.0 && veil_angle_deg < 90.0)) throw std::invalid_argument("veil_angle_deg must be in (0, 90)");
  if (!(veil_min_gap >= 0.0 && veil_min_gap < veil_radius))
    throw std::invalid_argument("veil_radius must exceed veil_min_gap (" + std::to_string(veil_min_gap) +
                                " m: closer points are one surface), and veil_min_gap must not be negative");
}

FruitInputStage::FruitInputStage(const FruitInputParams& params) : params_(params), red_(params.red_test) {
  params_.validate();
}

void FruitInputStage::removeOutliers(FruitInput* out) const {
  // The statistic needs more points than neighbours; a handful of fruit points stays as it is.
  if (!params_.remove_outliers || out->fruit.size() <= static_cast<std::size_t>(params_.outliers.k)) return;
  const std::vector<char> outlier = findStatisticalOutliers(out->fruit, params_.outliers);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < out->fruit.size(); ++i)
    if (!outlier[i]) out->fruit[kept++] = out->fruit[i];
  out->outliers = out->fruit.size() - kept;
  out->fruit.resize(kept);
}

FruitInput FruitInputStage::processFrame(const OrganizedFrame& frame, const Eigen::Isometry3d& camera_to_map,
                                         const std::vector<std::uint8_t>* external_mask, bool full_cloud) const {
  FruitInput out;
  out.error = frame.problem();
  if (out.ok() && external_mask && external_mask->size() != frame.pixels())
    out.error = "the mask has " + std::to_string(external_mask->size()) + " pixels, the frame " +
                std::to_string(frame.width) + " x " + std::to_string(frame.height);
  if (out.ok() && !camera_to_map.matrix().allFinite()) out.error = "the camera pose is not finite";
  if (!out.ok()) return out;
  const std::size_t n = frame.pixels();
  out.mask.assign(n, 0);
  if (full_cloud) out.full.reserve(n);
  for (std::size_t px = 0; px < n; ++px) {
    const float* p = &frame.xyz[3 * px];
    if (!(std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]))) continue;
    ++out.points;
    const std::uint8_t* c = &frame.rgb[3 * px];
    const bool fruit = external_mask ? (*external_mask)[px] != 0 : red_.isRed(c[0], c[1], c[2]);
    out.mask[px] = fruit ? 1 : 0;
    out.masked += fruit ? 1 : 0;
    if (full_cloud) out.full.push_back(camera_to_map * Eigen::Vector3d(p[0], p[1], p[2]));
  }
  std::vector<std::uint8_t> keep = out.mask;
  if (params_.drop_depth_edges)
    out.depth_edges = clearDepthEdges(frame.xyz.data() + 2, 3, frame.width, frame.height, &keep, params_.depth_edges);
  out.fruit.reserve(out.masked - out.depth_edges);
  for (std::size_t px = 0; px < n; ++px)
    if (keep[px]) {
      const float* p = &frame.xyz[3 * px];
      out.fruit.push_back(camera_to_map * Eigen::Vector3d(p[0], p[1], p[2]));
    }
  removeOutliers(&out);
  return out;
}

FruitInput FruitInputStage::processFruitCloud(const PointList& fruit) const {
  FruitInput out;
  out.fruit.reserve(fruit.size());
  for (const auto& p : fruit) {
    if (p.allFinite()) out.fruit.push_back(p);
    else ++out.non_finite;
  }
  out.points = fruit.size();
  removeOutliers(&out);
  return out;
}

FruitInput FruitInputStage::processRoiCloud(const PointList& all, const PointList& fruit,
                                            const Eigen::Vector3d& sensor_origin) const {
  FruitInput out;
  out.points = fruit.size();
  if (!sensor_origin.allFinite()) {
    out.error = "the sensor origin is not finite";
    return out;
  }
  for (const auto& p : fruit)
    if (!p.allFinite()) ++out.non_finite;
  if (!params_.drop_veil_points || all.empty()) {
    for (const auto& p : fruit)
      if (p.allFinite()) out.fruit.push_back(p);
    return out;
  }
  // A point with a neighbour nearly along its own camera ray lies where the depth jumps: the
  // blurred outline between a fruit and what is behind it, strung out along the rays.
  const double sin_limit = std::sin(params_.veil_angle_deg * M_PI / 180.0);
  const double min_gap2 = params_.veil_min_gap * params_.veil_min_gap;
  const auto isVeil = [&](const NeighbourGrid& grid, const Point& p) {
    const Eigen::Vector3d ray = (p - sensor_origin).normalized();
    bool veil = false;
    grid.forEachWithin(p, params_.veil_radius, [&](int, double d2, const Point& q) {
      if (veil || d2 < min_gap2) return;
      const Eigen::Vector3d v = q - p;
      veil = v.cross(ray).norm() < sin_limit * std::sqrt(d2);
    });
    return veil;
  };
  const auto judge = [&](bool veil, const Point& p) {
    if (veil) ++out.veil;
    else out.fruit.push_back(p);
  };
  // A fruit point reads the 27 cells of veil_radius around it. pointcloud_roi's 1 cm cloud puts
  // about ten points in a cell, so a view costs about a million tests; a raw camera cloud wired
  // here (hundreds per cell), or one point repeated, would cost billions on the caller's thread.
  constexpr double kMaxTests = 2e7;
  const NeighbourGrid grid(all, params_.veil_radius);
  if (static_cast<double>(fruit.size()) * 27.0 * grid.meanCellmates() <= kMaxTests) {
    for (const auto& p : fruit)
      if (p.allFinite()) judge(isVeil(grid, p), p);
    return out;
  }
  // Then both clouds are read in cells of half veil_min_gap: the first point of a cell stands for
  // the cloud there, and a fruit point takes the verdict of its cell's first fruit point.
  const double inv_cell = 1.0 / std::max(0.5 * params_.veil_min_gap, 0.02 * params_.veil_radius);
  struct CellHash {
    std::size_t operator()(const GridCell& c) const { return std::hash<std::uint64_t>()(packCellKey(c)); }
  };
  PointList firsts;
  {
    std::unordered_set<GridCell, CellHash> seen;
    for (const auto& q : all)
      if (q.allFinite() && seen.insert(cellOf(q, inv_cell)).second) firsts.push_back(q);
  }
  const NeighbourGrid thinned(firsts, params_.veil_radius);
  std::unordered_map<GridCell, bool, CellHash> verdicts;
  for (const auto& p : fruit) {
    if (!p.allFinite()) continue;
    const auto found = verdicts.try_emplace(cellOf(p, inv_cell), false);
    if (found.second) found.first->second = isVeil(thinned, p);
    judge(found.first->second, p);
  }
  return out;
}

}  // namespace fruit_shape_completion
