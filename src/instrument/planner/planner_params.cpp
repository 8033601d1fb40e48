#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>

#include <cmath>

namespace fruit_shape_completion {
namespace planner {

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

}  // namespace planner
}  // namespace fruit_shape_completion
