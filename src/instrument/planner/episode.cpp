// The stand-in planner's episode: capture a view (camera_step), insert it into the ROI octree
// and the estimators, score, pick the next view among sampled candidates (view_gain), move the
// arm there (arm_step); the clock as docs/design.md describes.
#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>
#include <fruit_shape_completion/instrument/sim/fruit_mask.h>

#include "arm_step.h"
#include "camera_step.h"
#include "view_gain.h"

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

  if (arm && !placeArmAtStart(scene, *arm, p.arm_motion, look, rng, &pos, &state)) {
    result.message = "the arm (" + scene.robot.describe() + ") reaches no view near the camera start; no views taken";
    return result;
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
      const CameraView captured = captureView(renderer, cam, p, red_test, view);
      const sim::RgbdFrame& frame = captured.frame;
      const std::vector<std::uint8_t>& mask = captured.mask;
      countMask(captured, red_fruit_material, &result);
      // The ideal profile's HSV test stands in for an external detector's mask; the paper
      // profile leaves the red test to the product's input stage.
      const ViewData given = captured.viewData(t, !p.upstream_red_test);
      for (std::size_t px = 0; px < mask.size(); ++px) {
        seen_points += std::isfinite(frame.depth[px]) ? 1 : 0;
        seen_fruit += mask[px];
      }
      const auto compute0 = std::chrono::steady_clock::now();  // the robot's own work starts here

      insertIntoOctree(&tree, captured, p);
      if (arm) known = occupiedField(tree, p.arm_map_resolution);
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
      result.final_fruits = scoreView(tree, truth, visibleNow().fruits, &rec);

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
          Eigen::Vector3d dir{g(rng), g(rng), g(rng)};
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
                                    (scene.workspace.box_max - scene.workspace.box_min).cwiseProduct(Eigen::Vector3d{unit(rng), unit(rng), unit(rng)});
          Eigen::Vector3d target;
          if (p.explore_plants)
            target = scene.plants.empty() ? plants_center
                                          : scene.plants[static_cast<std::size_t>(unit(rng) * scene.plants.size()) % scene.plants.size()].position +
                                                Eigen::Vector3d(0, 0, 0.2 + 0.5 * unit(rng));
          else if (!seen.empty())
            target = seen[static_cast<std::size_t>(unit(rng) * seen.size()) % seen.size()];
          else
            target = c + Eigen::Vector3d{g(rng), g(rng), 0.3 * g(rng)}.normalized();
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
        const Eigen::Vector3d turn = pos + Eigen::Vector3d{g(rng), g(rng), 0.2 * g(rng)}.normalized();
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
