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
  const UpstreamSamplingParams& s = sampling;
  if (!finite_pos(s.min_range) || !(s.max_range >= s.min_range) || !std::isfinite(s.max_range))
    return "sensor ranges must satisfy 0 < min_range <= max_range";
  if (s.roi_samples < 0 || s.expl_samples < 0 || s.roi_samples + s.expl_samples < 1)
    return "roi_samples and expl_samples must be >= 0, one of them > 0";
  if (!finite_pos(s.inflation_resolution) || !finite_pos(s.inflation_radius))
    return "inflation_resolution and inflation_radius must be > 0";
  if (!(std::isfinite(s.travel_weight) && s.travel_weight >= 0.0)) return "travel_weight must be >= 0";
  if (!std::isfinite(s.roi_threshold)) return "roi_threshold must be finite";
  if (!(std::isfinite(ik_failure_cost) && ik_failure_cost >= 0.0) || !(std::isfinite(plan_failure_cost) && plan_failure_cost >= 0.0))
    return "ik_failure_cost and plan_failure_cost must be >= 0";
  if (!finite_pos(retry_cost)) return "retry_cost must be > 0";
  if (!(octree_resolution >= 0.001 && octree_resolution <= 0.5)) return "octree_resolution must be in [0.001, 0.5] m";
  if (!(std::isfinite(clearance) && clearance >= 0.0)) return "clearance must be >= 0";
  if (render_threads < 1) return "render_threads must be >= 1";
  if (!(std::isfinite(trolley_move_length) && trolley_move_length >= 0.0)) return "trolley_move_length must be >= 0";
  if (trolley_move_length > 0.0 &&
      (!finite_pos(trolley_time_per_segment) || !finite_pos(trolley_speed) ||
       !(std::isfinite(trolley_window_margin) && trolley_window_margin >= 0.0)))
    return "trolley_time_per_segment and trolley_speed must be > 0, trolley_window_margin >= 0";
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
