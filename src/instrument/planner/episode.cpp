// The stand-in planner's episode: capture a view (camera_step), insert it into the ROI octree
// and the estimators, score, sample candidates as upstream does (upstream_sampling), try them
// best first with the arm (arm_step); the clock as docs/design.md describes.
#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>
#include <fruit_shape_completion/instrument/sim/fruit_mask.h>

#include "arm_step.h"
#include "camera_step.h"

#include <octomap/octomap_types.h>

#include <algorithm>
#include <fstream>
#include <unistd.h>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <unordered_set>

namespace fruit_shape_completion {
namespace planner {

namespace {
// Resident memory of this process (Linux /proc/self/statm), 0 where unknown.
double residentMiB() {
  std::ifstream statm("/proc/self/statm");
  double pages_total = 0, pages_resident = 0;
  if (!(statm >> pages_total >> pages_resident)) return 0.0;
  return pages_resident * static_cast<double>(sysconf(_SC_PAGESIZE)) / 1048576.0;
}
}  // namespace

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
  RoiOcTree tree(p.octree_resolution);
  Eigen::Vector3d pos = scene.camera_start_position;
  const Eigen::Vector3d look = scene.camera_start_look_at;
  double t = 0.0, last_update = -1e300;
  // The estimators' results as the planner sees them, and a fit still running (in simulated time).
  // Shared with the estimator, as a planner holds them: nothing is copied per update.
  struct FitResults {
    std::shared_ptr<const std::vector<FruitEstimate>> fruits = std::make_shared<const std::vector<FruitEstimate>>();
    std::shared_ptr<const ShapeTargets> targets = std::make_shared<const ShapeTargets>();
  } visible, fit;
  bool fit_pending = false;
  double fit_ready = -1e300;
  sim::RedThreshold red_test;
  if (p.upstream_red_test) red_test.test = sim::RedThreshold::Test::kUpstream;
  // What the mask should find: fruit materials whose colour is red (the paper scores red fruit).
  std::vector<char> red_fruit_material;
  for (const auto& m : scene.materials) red_fruit_material.push_back(m.fruit && sim::colorClass(m.rgb) == "red");

  // The trolley's window of the workspace: the planner samples there and the arm's base stays
  // there; the whole workspace without a trolley.
  sim::Workspace workspace = scene.workspace;
  double trolley_x = pos.x();
  int segment = 0;
  auto placeWindow = [&]() {
    if (!(p.trolley_move_length > 0.0)) return;
    const double half = 0.5 * p.trolley_move_length + p.trolley_window_margin;
    workspace.box_min.x() = std::max(scene.workspace.box_min.x(), trolley_x - half);
    workspace.box_max.x() = std::min(scene.workspace.box_max.x(), trolley_x + half);
    if (arm)
      arm->setBaseRange(Eigen::Vector2d(std::max(scene.robot.xy_min.x(), trolley_x - half), scene.robot.xy_min.y()),
                        Eigen::Vector2d(std::min(scene.robot.xy_max.x(), trolley_x + half), scene.robot.xy_max.y()));
  };
  placeWindow();
  if (arm && !placeArmAtStart(scene, *arm, p.arm_motion, look, rng, &pos, &state)) {
    result.message = "the arm (" + scene.robot.describe() + ") reaches no view near the camera start; no views taken";
    return result;
  }

  sim::DistanceField known;                  // what the planner's map has seen occupied
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
  // The camera's orientation carries over from view to view: upstream turns the current one the
  // least that points it at the next target (dirVecToQuat), so its roll drifts as the robot's does.
  Eigen::Matrix3d rot = PinholeCamera::lookingAt(pos, look).rotation;
  bool capture = true;            // the camera moved: a new view (the first one too)
  int rounds_without_choice = 0;  // rounds whose chosen list was empty
  int view = 0;
  for (;;) {
    // The trolley's next segment: it carries the arm, camera and window along the row.
    if (p.trolley_move_length > 0.0 && t >= (segment + 1) * p.trolley_time_per_segment) {
      ++segment;
      if (trolley_x + p.trolley_move_length <= scene.workspace.box_max.x()) {
        trolley_x += p.trolley_move_length;
        t += p.trolley_move_length / p.trolley_speed;
        pos.x() += p.trolley_move_length;
        if (arm) state.base.x() += p.trolley_move_length;
        placeWindow();
        ++result.trolley_moves;
        capture = true;
      }
    }
    t += capture ? p.view_cost : p.retry_cost;
    if (t > p.duration) break;
    // A view or round that fails (out of memory, a throwing callback) is dropped and counted;
    // the episode goes on from where the camera is.
    try {
      const auto wall0 = std::chrono::steady_clock::now();
      auto compute0 = wall0;  // the robot's own work starts here
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
      ViewRecord rec;
      std::optional<ViewData> given;  // refers to `captured`
      CameraView captured;
      if (capture) {
        PinholeCamera cam;
        cam.position = pos;
        cam.rotation = rot;
        captured = captureView(renderer, cam, p, red_test, view);
        countMask(captured, red_fruit_material, &result);
        // The ideal profile's HSV test stands in for an external detector's mask; the paper
        // profile leaves the red test to the product's input stage.
        given.emplace(captured.viewData(t, !p.upstream_red_test));
        for (std::size_t px = 0; px < captured.mask.size(); ++px) {
          seen_points += std::isfinite(captured.frame.depth[px]) ? 1 : 0;
          seen_fruit += captured.mask[px];
        }
        compute0 = std::chrono::steady_clock::now();

        insertIntoOctree(&tree, captured);
        if (arm) known = occupiedField(tree, p.arm_map_resolution);
        // The planner blocks only on insertView; the fit runs beside it (as the plugin's worker
        // does). Its results reach the planner at the simulated time they would be ready, the
        // fit's start plus its measured duration, and one fit runs at a time: views during a fit
        // wait for the next one.
        const auto insert0 = std::chrono::steady_clock::now();
        host.insertView(*given);
        rec.insert_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - insert0).count();
        visibleNow();  // a finished fit's results first: the next fit must not overwrite them
        if (clockNow() >= fit_ready && t - last_update >= p.estimator_period) {
          const double start = clockNow();
          const auto fit0 = std::chrono::steady_clock::now();
          host.update();
          fit.fruits = host.sharedFruits(0);
          fit.targets = p.shape_targets ? host.sharedViewTargets() : std::make_shared<const ShapeTargets>();
          fit_wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - fit0).count();
          fit_ready = start + (p.charge_compute_time ? fit_wall : 0.0);
          fit_pending = true;
          last_update = t;
        }
        rec.view = view;
        rec.time = t;
        rec.position = pos;
        result.final_fruits = scoreView(tree, truth, *visibleNow().fruits, &rec);
      }

      // ViewpointPlanner::plannerLoopOnce: sample both lists, take one, try it best first.
      ++result.planning_rounds;
      static const ShapeTargets kNoTargets;
      const std::shared_ptr<const ShapeTargets> held = visibleNow().targets;  // alive for the round
      const ShapeTargets& extra = p.shape_targets ? *held : kNoTargets;
      const SampledCandidates sampled = sampleUpstream(tree, workspace, extra, pos, p.sampling, rng);
      const std::vector<SampledView>& chosen = sampled.chosen();
      rec.contour_targets = static_cast<int>(sampled.roi_pool - extra.points.size());
      rec.shape_targets = static_cast<int>(extra.points.size());
      rec.exploration = !sampled.use_roi;
      rec.gain = chosen.empty() ? 0.0 : chosen.front().gain;
      double travel = 0.0;  // [s] of a successful move, charged after the round's compute
      bool moved = false;
      for (const SampledView& c : chosen) {
        ++rec.attempts;
        ++result.sampled_views;
        PinholeCamera goal;
        goal.position = c.origin;
        goal.rotation = turnTowards(rot, c.direction);
        if (arm) {
          sim::ArmState reached;
          switch (arm->reach(goal, state, p.arm_motion, known, &reached)) {
            case sim::RobotArm::Reach::kReached: ++result.reachable_views; break;
            case sim::RobotArm::Reach::kNoInverse: ++result.unreachable_ik; t += p.ik_failure_cost; continue;
            case sim::RobotArm::Reach::kJointLimits: ++result.unreachable_limits; t += p.ik_failure_cost; continue;
            case sim::RobotArm::Reach::kCollision: ++result.unreachable_collision; t += p.plan_failure_cost; continue;
          }
          if (!moveArm(reached)) {  // executed into unseen plants: upstream tries the next
            result.failed_moves_shape += c.shape_target ? 1 : 0;
            continue;
          }
        } else {
          // The free-flying camera: MoveIt's collision check against the true scene.
          if (!renderer.isClear(c.origin, p.clearance)) {
            ++result.unreachable_collision;
            t += p.plan_failure_cost;
            continue;
          }
          ++result.reachable_views;
          travel = (c.origin - pos).norm() / p.speed;
        }
        pos = c.origin;
        rot = goal.rotation;
        moved = true;
        rec.to_shape_target = c.shape_target;
        ++result.moves;
        result.moves_shape += c.shape_target ? 1 : 0;
        break;
      }
      const auto done = std::chrono::steady_clock::now();
      const double compute_ms = std::chrono::duration<double, std::milli>(done - compute0).count() - 1e3 * fit_wall;
      if (p.charge_compute_time) t += compute_ms / 1000.0;
      t += travel;
      if (!moved) ++result.rounds_without_move;
      rounds_without_choice = chosen.empty() ? rounds_without_choice + 1 : 0;
      if (capture) {
        rec.wall_ms = std::chrono::duration<double, std::milli>(done - wall0).count();
        rec.compute_ms = compute_ms;
        rec.fit_ms = 1e3 * fit_wall;
        rec.rss_mib = residentMiB();
        result.views.push_back(rec);
        ++view;
        if (on_view && !on_view(rec, tree, captured.frame, *given)) {
          if (result.message.empty()) result.message = "stopped by the caller";
          break;
        }
      }
      capture = moved;
      // Upstream would sample on forever; nothing changes here until a fit lands.
      if (rounds_without_choice >= 3 && !fit_pending) {
        if (result.message.empty()) result.message = "no view in the workspace sees anything new; episode ended early";
        break;
      }
    } catch (const std::exception& e) {
      if (result.dropped_views++ == 0) result.dropped_reason = e.what();
      capture = true;
    }
  }
  if (!result.views.empty() && (seen_points == 0 || seen_fruit == 0)) {
    std::ostringstream os;
    if (seen_points == 0)
      os << "nothing can be seen from the workspace: " << result.views.size() << " views returned no depth";
    else
      os << "nothing red was seen in " << result.views.size() << " views: no fruit to measure";
    if (!result.message.empty()) os << "; " << result.message;
    result.message = os.str();
  }
  return result;
}

}  // namespace planner
}  // namespace fruit_shape_completion
