#include <fruit_shape_completion/planner/pointcloud_roi.h>
#include <fruit_shape_completion/planner/viewpoint_planner.h>
#include <fruit_shape_completion/sim/fruit_mask.h>

#include <octomap/octomap_types.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <unordered_set>

namespace fruit_shape_completion {
namespace planner {

namespace {

using KeySet = std::unordered_set<std::uint64_t>;

std::uint64_t coarseKey(const RoiOcTree& tree, const Eigen::Vector3d& p) {
  const octomap::OcTreeKey k = tree.key(p);
  return (static_cast<std::uint64_t>(k[0] >> 2) << 32) | (static_cast<std::uint64_t>(k[1] >> 2) << 16) | (k[2] >> 2);
}

// 4 cm cells around the targets: unknown space there is worth seeing.
KeySet interestCells(const RoiOcTree& tree, const PointList& targets) {
  KeySet cells;
  const double s = 4 * tree.getResolution();
  for (const auto& t : targets)
    for (int x = -1; x <= 1; ++x)
      for (int y = -1; y <= 1; ++y)
        for (int z = -1; z <= 1; ++z) cells.insert(coarseKey(tree, t + s * Eigen::Vector3d(x, y, z)));
  return cells;
}

// Unknown octree cells seen along a grid of camera rays (stopping at occupied cells); only
// those in `interest` count unless interest is null.
double viewGain(const RoiOcTree& tree, const PinholeCamera& cam, const PlannerParams& p, const KeySet* interest) {
  double gain = 0.0;
  octomap::KeyRay ray;
  const octomap::point3d o(cam.position.x(), cam.position.y(), cam.position.z());
  for (int j = 0; j < p.utility_rays_y; ++j)
    for (int i = 0; i < p.utility_rays_x; ++i) {
      const int u = static_cast<int>((i + 0.5) * cam.width / p.utility_rays_x);
      const int v = static_cast<int>((j + 0.5) * cam.height / p.utility_rays_y);
      const Eigen::Vector3d end = cam.position + p.utility_range * cam.rayDirection(u, v);
      if (!tree.computeRayKeys(o, octomap::point3d(end.x(), end.y(), end.z()), ray)) continue;
      for (const auto& k : ray) {
        const RoiOcTreeNode* n = tree.search(k);
        if (n != nullptr) {
          if (tree.isNodeOccupied(n)) break;
          continue;
        }
        if (interest == nullptr || interest->count(coarseKey(tree, tree.center(k)))) gain += 1.0;
      }
    }
  return gain;
}

}  // namespace

const char* toString(PlannerParams::Input input) {
  switch (input) {
    case PlannerParams::Input::kCamera: return "camera";
    case PlannerParams::Input::kRoi: return "roi";
    case PlannerParams::Input::kFruitCloud: return "fruit-cloud";
  }
  return "?";
}

bool parseInput(const std::string& name, PlannerParams::Input* input) {
  for (auto i : {PlannerParams::Input::kCamera, PlannerParams::Input::kRoi, PlannerParams::Input::kFruitCloud})
    if (name == toString(i)) {
      *input = i;
      return true;
    }
  return false;
}

SceneTruth makeSceneTruth(const std::vector<sim::FruitTruth>& fruits, double resolution) {
  SceneTruth truth;
  truth.box_resolution = resolution;
  for (const auto& f : fruits) {
    if (f.color != "red") {  // the paper scores red fruit; others may not match an estimate either
      truth.not_scored.push_back(f.center);
      continue;
    }
    truth.enclosed.push_back({f.center, f.volume});
    truth.se.push_back({f.se.t, f.se_volume});
    // Centres of the voxels holding the extreme vertices: floor(x / res) + 0.5, per axis.
    const Eigen::Vector3d lo = ((f.box_min / resolution).array().floor() + 0.5) * resolution;
    const Eigen::Vector3d hi = ((f.box_max / resolution).array().floor() + 0.5) * resolution;
    const double volume = std::max((hi - lo).prod(), std::pow(resolution, 3));  // never 0: accuracy divides by it
    truth.box.push_back({0.5 * (lo + hi), volume});
  }
  return truth;
}

std::vector<FruitEstimate> SceneTruth::scoredEstimates(std::vector<FruitEstimate> estimates) const {
  if (not_scored.empty()) return estimates;
  auto nearest = [](const Eigen::Vector3d& c, const std::vector<Eigen::Vector3d>& points) {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& p : points) best = std::min(best, (p - c).norm());
    return best;
  };
  std::vector<Eigen::Vector3d> scored;
  for (const auto& t : enclosed) scored.push_back(t.center);
  estimates.erase(std::remove_if(estimates.begin(), estimates.end(),
                                 [&](const FruitEstimate& e) {
                                   return nearest(e.center(), not_scored) < nearest(e.center(), scored);
                                 }),
                  estimates.end());
  return estimates;
}

std::string PlannerParams::problem() const {
  auto finite_pos = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!(std::isfinite(duration) && duration >= 0.0)) return "duration must be >= 0";
  if (!finite_pos(view_cost)) return "view_cost must be > 0";
  if (!finite_pos(speed)) return "speed must be > 0";
  if (!(roi_leaf >= 0.001 && roi_leaf <= 0.1)) return "roi_leaf must be in [0.001, 0.1] m";
  if (!finite_pos(min_view_distance) || !(max_view_distance >= min_view_distance) || !std::isfinite(max_view_distance))
    return "view distances must satisfy 0 < min_view_distance <= max_view_distance";
  if (candidates < 1) return "candidates must be >= 1";
  if (utility_rays_x < 1 || utility_rays_y < 1) return "utility_rays_x/y must be >= 1";
  if (!finite_pos(utility_range)) return "utility_range must be > 0";
  if (!(std::isfinite(travel_weight) && travel_weight >= 0.0)) return "travel_weight must be >= 0";
  if (!(octree_resolution >= 0.001 && octree_resolution <= 0.5)) return "octree_resolution must be in [0.001, 0.5] m";
  if (octree_pixel_step < 1) return "octree_pixel_step must be >= 1";
  if (!finite_pos(octree_max_range)) return "octree_max_range must be > 0";
  if (!(std::isfinite(clearance) && clearance >= 0.0)) return "clearance must be >= 0";
  if (render_threads < 1) return "render_threads must be >= 1";
  if (!(std::isfinite(estimator_period) && estimator_period >= 0.0)) return "estimator_period must be >= 0";
  if (arm) {
    const std::string m = arm_motion.problem();
    if (!m.empty()) return m;
    if (!(arm_collision_resolution >= 0.002 && arm_collision_resolution <= 0.1))
      return "arm_collision_resolution must be in [0.002, 0.1] m";
    if (!(arm_map_resolution >= 0.005 && arm_map_resolution <= 0.1)) return "arm_map_resolution must be in [0.005, 0.1] m";
  }
  return {};
}

PlannerParams paperProfile(PlannerParams p) {
  p.paper_depth_noise = true;
  p.textures = true;
  p.upstream_red_test = true;
  p.explore_plants = false;
  p.estimator_period = 3.0;  // the paper's surface cloud came every 3 s
  p.charge_compute_time = true;
  p.arm = true;
  // Per plan: a MoveIt planning request, the trajectory's start and settling, and waiting for a
  // fresh frame before the next plan.
  p.view_cost = 1.5;
  return p;
}

EpisodeResult runEpisode(const sim::Scene& scene, const sim::RgbdRenderer& renderer,
                         const SceneTruth& truth, ShapeEstimatorHost& host, const PlannerParams& p,
                         const ViewCallback& on_view) {
  EpisodeResult result;
  result.truth_fruits = static_cast<int>(truth.enclosed.size());
  std::string bad = p.problem();
  if (bad.empty() && !truth.box.empty() && std::abs(truth.box_resolution - p.octree_resolution) > 1e-9)
    bad = "the ground-truth boxes were made for " + std::to_string(truth.box_resolution) + " m cells, the octree has " +
          std::to_string(p.octree_resolution) + " m (makeSceneTruth with params.octree_resolution)";
  if (!bad.empty()) {
    result.message = "bad planner parameters: " + bad + "; no views taken";
    return result;
  }
  if (!scene.workspace.contains(scene.camera_start_position)) {
    std::ostringstream os;
    os << "camera start (" << scene.camera_start_position.transpose()
       << ") is outside the workspace; no views taken";
    result.message = os.str();
    return result;
  }
  if (truth.enclosed.empty()) result.message = "the scene has no ground-truth fruits; figures stay zero";
  std::unique_ptr<sim::RobotArm> arm;
  sim::ArmState state;
  if (p.arm) {
    if (scene.robot.kind == sim::RobotMount::Kind::kNone) {
      result.message = "the planner was asked to move the arm, but the scene has no robot mount; no views taken";
      return result;
    }
    arm = std::make_unique<sim::RobotArm>(scene, p.arm_collision_resolution);
  }

  std::mt19937 rng(p.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  RoiOcTree tree(p.octree_resolution);
  Eigen::Vector3d pos = scene.camera_start_position, look = scene.camera_start_look_at;
  double t = 0.0, last_update = -1e300;
  // The estimators' results as the planner sees them, and a fit still running (in simulated time).
  struct FitResults {
    std::vector<FruitEstimate> fruits;
    PointList targets;
  } visible, fit;
  bool fit_pending = false;
  double fit_ready = -1e300;
  sim::RedThreshold red_test;
  if (p.upstream_red_test) red_test.test = sim::RedThreshold::Test::kUpstream;
  // What the mask should find: fruit materials whose colour is red (the paper scores red fruit).
  std::vector<char> red_fruit_material;
  for (const auto& m : scene.materials) red_fruit_material.push_back(m.fruit && sim::colorClass(m.rgb) == "red");
  int views_without_gain = 0;
  Eigen::Vector3d plants_center = Eigen::Vector3d::Zero();
  for (const auto& pl : scene.plants) plants_center += pl.position / std::max<std::size_t>(1, scene.plants.size());

  if (arm) {
    // Start from a home posture near the start view, then the start view itself or, if the arm
    // cannot take it, the nearest reachable view looking at the same point.
    sim::ArmState home;
    home.q << 0, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0;
    home.base = scene.robot.kind == sim::RobotMount::Kind::kPole
                    ? scene.robot.base
                    : Eigen::Vector3d(std::clamp(pos.x(), scene.robot.xy_min.x(), scene.robot.xy_max.x()),
                                      std::clamp(pos.y(), scene.robot.xy_min.y(), scene.robot.xy_max.y()), scene.robot.top);
    std::normal_distribution<double> g(0.0, 1.0);
    bool placed = false;
    for (int i = 0; i < 2000 && !placed; ++i) {
      const Eigen::Vector3d c = i == 0 ? pos : pos + (0.02 + 0.3 * i / 2000.0) * Eigen::Vector3d(g(rng), g(rng), g(rng));
      if ((c - look).norm() < 0.05 || !scene.workspace.contains(c)) continue;
      placed = arm->reach(PinholeCamera::lookingAt(c, look), home, p.arm_motion, arm->plants(), &state) ==
               sim::RobotArm::Reach::kReached;
      if (placed) pos = c;
    }
    if (!placed) {
      result.message = "the arm (" + scene.robot.describe() + ") reaches no view near the camera start; no views taken";
      return result;
    }
  }

  sim::DistanceField known;                  // what the planner's map has seen occupied
  std::vector<Eigen::Vector3d> failed_goals;  // views whose move failed: not planned again
  // Executes a move planned in the map: the plants decide whether the arm gets there. A failed
  // move costs its time and leaves the arm where it was.
  auto moveArm = [&](const sim::ArmState& goal) {
    t += arm->motionTime(state, goal, p.arm_motion);
    if (arm->collides(goal, arm->plants())) {
      ++result.failed_moves;
      return false;
    }
    state = goal;
    return true;
  };

  std::size_t seen_points = 0, seen_fruit = 0;
  for (int view = 0;; ++view) {
    t += p.view_cost;
    if (t > p.duration) break;
    // A view that fails (out of memory, a throwing callback) is dropped and counted; the
    // episode goes on from where the camera is.
    try {
      const auto wall0 = std::chrono::steady_clock::now();
      const PinholeCamera cam = PinholeCamera::lookingAt(pos, look);
      sim::DepthNoise noise;
      noise.enabled = p.depth_noise;
      if (p.paper_depth_noise) noise.model = sim::DepthNoise::Model::kPaper;
      noise.seed = p.seed * 100003u + static_cast<unsigned>(view);
      const sim::RgbdFrame frame = renderer.render(cam, noise, p.render_threads);
      const std::vector<std::uint8_t> mask = sim::redMask(frame.rgb, frame.width, frame.height, red_test);
      for (std::size_t px = 0; px < mask.size(); ++px) {
        const int m = frame.material[px];
        if (m < 0) continue;
        if (red_fruit_material[static_cast<std::size_t>(m)]) {
          ++result.mask_positives;
          result.mask_false_negatives += !mask[px];
        } else {
          ++result.mask_negatives;
          result.mask_false_positives += mask[px];
        }
      }
      // The estimators get what the chosen input delivers to the plugin on a robot; the product's
      // fruit input stage (in the estimator) does the rest. The ideal profile's HSV test stands in
      // for an external detector's mask.
      const Eigen::Isometry3d pose = sim::cameraPose(cam);
      OrganizedFrame organized;
      PointList fruit_points, all_points;
      ViewSource source = ViewSource::kCameraFrame;
      switch (p.input) {
        case PlannerParams::Input::kCamera:
          organized = sim::organizedFrame(frame);
          break;
        case PlannerParams::Input::kRoi: {
          RoiCloud roi = pointcloudRoi(frame, p.roi_leaf, red_test);
          for (const auto i : roi.roi_indices) fruit_points.push_back(roi.points[static_cast<std::size_t>(i)]);
          all_points = std::move(roi.points);
          source = ViewSource::kRoiCloud;
          break;
        }
        case PlannerParams::Input::kFruitCloud:
          fruit_points = sim::cloudsFromFrame(frame, mask).fruit;
          source = ViewSource::kFruitCloud;
          break;
      }
      ViewData given{fruit_points, all_points, pose, t, source};
      if (source == ViewSource::kCameraFrame) {
        given.camera_frame = &organized;
        if (!p.upstream_red_test) given.fruit_mask = &mask;
      }
      for (std::size_t px = 0; px < mask.size(); ++px) {
        seen_points += std::isfinite(frame.depth[px]) ? 1 : 0;
        seen_fruit += mask[px];
      }
      const auto compute0 = std::chrono::steady_clock::now();  // the robot's own work starts here

      // The octree gets a pixel subsample with the colour mask (its 1 cm cells need no more).
      PointList octree_points;
      std::vector<char> octree_fruit;
      const double f = 0.5 * cam.width / std::tan(0.5 * cam.hfov_rad);
      for (int v = 0; v < frame.height; v += p.octree_pixel_step)
        for (int u = 0; u < frame.width; u += p.octree_pixel_step) {
          const std::size_t px = static_cast<std::size_t>(v) * frame.width + u;
          const double z = frame.depth[px];
          if (!std::isfinite(z)) continue;
          octree_points.push_back(cam.position +
                                  cam.rotation * Eigen::Vector3d((u + 0.5 - 0.5 * cam.width) / f * z,
                                                                 (v + 0.5 - 0.5 * cam.height) / f * z, z));
          octree_fruit.push_back(mask[px] ? 1 : 0);
        }
      tree.insertScan(octree_points, octree_fruit, cam.position, p.octree_max_range);
      if (arm) {
        // Occupied cells as points; a merged leaf (8^k equal cells) as a grid over its cube.
        PointList occupied;
        for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
          if (!tree.isNodeOccupied(*it)) continue;
          const Eigen::Vector3d c(it.getX(), it.getY(), it.getZ());
          const double size = it.getSize();
          const int n = std::max(1, static_cast<int>(std::ceil(size / p.arm_map_resolution)));
          for (int x = 0; x < n; ++x)
            for (int y = 0; y < n; ++y)
              for (int z = 0; z < n; ++z)
                occupied.push_back(c + size * (Eigen::Vector3d(x, y, z) + Eigen::Vector3d::Constant(0.5)) / n -
                                   Eigen::Vector3d::Constant(0.5 * size));
        }
        known = sim::DistanceField::ofPoints(occupied, p.arm_map_resolution, 0.2);
      }
      // The planner blocks only on insertView; the fit runs beside it (as the plugin's worker
      // does). Its results reach the planner at the simulated time they would be ready, the
      // fit's start plus its measured duration, and one fit runs at a time: views during a fit
      // wait for the next one.
      double fit_wall = 0.0;  // [s] measured here, but not the planner's time
      auto clockNow = [&] {
        if (!p.charge_compute_time) return t;
        return t + std::chrono::duration<double>(std::chrono::steady_clock::now() - compute0).count() - fit_wall;
      };
      auto visibleNow = [&]() -> const FitResults& {
        if (fit_pending && clockNow() >= fit_ready) {
          visible = std::move(fit);
          fit_pending = false;
        }
        return visible;
      };
      host.insertView(given);
      visibleNow();  // a finished fit's results first: the next fit must not overwrite them
      if (clockNow() >= fit_ready && t - last_update >= p.estimator_period) {
        const double start = clockNow();
        const auto fit0 = std::chrono::steady_clock::now();
        host.update();
        fit.fruits = host.fruits(0);
        fit.targets = p.shape_targets ? host.extraTargets() : PointList();
        fit_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - fit0).count();
        fit_ready = start + (p.charge_compute_time ? fit_wall : 0.0);
        fit_pending = true;
        last_update = t;
      }

      ViewRecord rec;
      rec.view = view;
      rec.time = t;
      rec.position = pos;
      std::vector<FruitEstimate> old_fruits, se_fruits;
      for (const auto& c : tree.roiClusters(10)) old_fruits.push_back(FruitEstimate::ofBox(c.center(), c.volume()));
      old_fruits = truth.scoredEstimates(std::move(old_fruits));
      se_fruits = truth.scoredEstimates(visibleNow().fruits);
      rec.old_true = evaluate(old_fruits, truth.enclosed);
      rec.se_true = evaluate(se_fruits, truth.enclosed);
      rec.old_se = evaluate(old_fruits, truth.se);
      rec.se_se = evaluate(se_fruits, truth.se);
      rec.old_box = evaluate(old_fruits, truth.box);
      result.final_fruits = se_fruits;

      // Targets and the next view.
      PointList targets = tree.roiContourTargets();
      rec.contour_targets = static_cast<int>(targets.size());
      if (p.shape_targets) {
        const PointList& extra = visibleNow().targets;
        rec.shape_targets = static_cast<int>(extra.size());
        targets.insert(targets.end(), extra.begin(), extra.end());
      }
      const KeySet interest = interestCells(tree, targets);
      struct Candidate {
        Eigen::Vector3d pos, look;
        double gain;
        sim::ArmState state;
      };
      std::vector<Candidate> cands;
      // The arm's inverse kinematics and collision checks run here, on the planning clock.
      auto tryCandidate = [&](const Eigen::Vector3d& c, const Eigen::Vector3d& target, const KeySet* interest_set) {
        if (!scene.workspace.contains(c) || (c - target).norm() < 1e-3) return;
        const PinholeCamera cc = PinholeCamera::lookingAt(c, target);
        sim::ArmState reached;
        if (arm) {
          for (const auto& f : failed_goals)
            if ((f - c).norm() < 0.02) return;
          ++result.sampled_views;
          switch (arm->reach(cc, state, p.arm_motion, known, &reached)) {
            case sim::RobotArm::Reach::kReached: ++result.reachable_views; break;
            case sim::RobotArm::Reach::kNoInverse: ++result.unreachable_ik; return;
            case sim::RobotArm::Reach::kJointLimits: ++result.unreachable_limits; return;
            case sim::RobotArm::Reach::kCollision: ++result.unreachable_collision; return;
          }
        } else if (!renderer.isClear(c, p.clearance)) {
          return;
        }
        cands.push_back({c, target, viewGain(tree, cc, p, interest_set), reached});
      };
      // Without an arm every sample is a candidate; with one, unreachable samples are replaced,
      // up to four times as many tries.
      auto enough = [&](int tries) { return tries >= 4 * p.candidates || (!arm && tries >= p.candidates) ||
                                            static_cast<int>(cands.size()) >= p.candidates; };
      std::normal_distribution<double> g(0.0, 1.0);
      if (!targets.empty()) {
        for (int i = 0; !enough(i); ++i) {
          const Eigen::Vector3d& target = targets[static_cast<std::size_t>(unit(rng) * targets.size()) % targets.size()];
          Eigen::Vector3d dir(g(rng), g(rng), g(rng));
          dir.normalize();
          const double dist = p.min_view_distance + unit(rng) * (p.max_view_distance - p.min_view_distance);
          tryCandidate(target + dist * dir, target, &interest);
        }
      }
      double best_gain = 0.0;
      for (const auto& c : cands) best_gain = std::max(best_gain, c.gain);
      if (best_gain <= 0.0) {  // exploration: anywhere in the workspace
        rec.exploration = true;
        cands.clear();
        // Without ground truth, look at what the map has seen occupied, or anywhere.
        PointList seen;
        if (!p.explore_plants)
          for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
            if (tree.isNodeOccupied(*it)) seen.emplace_back(it.getX(), it.getY(), it.getZ());
        for (int i = 0; !enough(i); ++i) {
          const Eigen::Vector3d c = scene.workspace.box_min +
                                    (scene.workspace.box_max - scene.workspace.box_min).cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
          Eigen::Vector3d target;
          if (p.explore_plants)
            target = scene.plants.empty() ? plants_center
                                          : scene.plants[static_cast<std::size_t>(unit(rng) * scene.plants.size()) % scene.plants.size()].position +
                                                Eigen::Vector3d(0, 0, 0.2 + 0.5 * unit(rng));
          else if (!seen.empty())
            target = seen[static_cast<std::size_t>(unit(rng) * seen.size()) % seen.size()];
          else
            target = c + Eigen::Vector3d(g(rng), g(rng), 0.3 * g(rng)).normalized();
          tryCandidate(c, target, nullptr);
        }
        best_gain = 0.0;
        for (const auto& c : cands) best_gain = std::max(best_gain, c.gain);
      }
      rec.gain = best_gain;
      const auto done = std::chrono::steady_clock::now();
      rec.wall_ms = std::chrono::duration<double, std::milli>(done - wall0).count();
      rec.compute_ms = std::chrono::duration<double, std::milli>(done - compute0).count() - 1e3 * fit_wall;
      rec.fit_ms = 1e3 * fit_wall;
      if (p.charge_compute_time) t += rec.compute_ms / 1000.0;
      result.views.push_back(rec);
      if (on_view && !on_view(rec, tree, frame, given)) {
        if (result.message.empty()) result.message = "stopped by the caller";
        break;
      }
      if (cands.empty() || best_gain <= 0.0) {
        if (++views_without_gain >= 3) {
          if (result.message.empty()) result.message = "no view in the workspace sees anything new; episode ended early";
          break;
        }
        // Stay, but turn to look elsewhere (if the arm can).
        const Eigen::Vector3d turn = pos + Eigen::Vector3d(g(rng), g(rng), 0.2 * g(rng)).normalized();
        sim::ArmState turned;
        if (!arm) {
          look = turn;
        } else if (arm->reach(PinholeCamera::lookingAt(pos, turn), state, p.arm_motion, known, &turned) ==
                       sim::RobotArm::Reach::kReached &&
                   moveArm(turned)) {
          look = turn;
        }
        continue;
      }
      views_without_gain = 0;
      const Candidate* best = nullptr;
      double best_u = -1e300;
      for (const auto& c : cands) {
        const double u = c.gain / best_gain - p.travel_weight * (c.pos - pos).norm();
        if (u > best_u) {
          best_u = u;
          best = &c;
        }
      }
      if (arm) {
        if (!moveArm(best->state)) {
          failed_goals.push_back(best->pos);
          continue;
        }
      } else {
        t += (best->pos - pos).norm() / p.speed;
      }
      pos = best->pos;
      look = best->look;
    } catch (const std::exception& e) {
      if (result.dropped_views++ == 0) result.dropped_reason = e.what();
    }
  }
  if (!result.views.empty() && result.message.empty()) {
    std::ostringstream os;
    if (seen_points == 0)
      os << "nothing can be seen from the workspace: " << result.views.size() << " views returned no depth";
    else if (seen_fruit == 0)
      os << "nothing red was seen in " << result.views.size() << " views: no fruit to measure";
    result.message = os.str();
  }
  return result;
}

}  // namespace planner
}  // namespace fruit_shape_completion
