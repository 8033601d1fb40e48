#pragma once
// A next-best-view loop over a simulated scene, standing in for roi_viewpoint_planner in its
// default automatic mode: render a view, insert it into the ROI octree, hand it to the shape
// estimators, sample ROI-contour views (with the estimators' predicted surface in the target
// pool, as the integration patch adds it) and contour exploration views, score them by
// ROI_VICINITY_UTILITY (upstream_sampling.h), take the ROI views when the best scores above 0.2,
// else the exploration views, and try them best first until a move succeeds. Every attempt
// costs simulated time: a failed inverse kinematics or motion plan its planning time, a
// successful one `view_cost` (plan, settle, fresh frame) plus the travel, either the camera
// flying at `speed` or (params.arm) the scene's UR5e moving in joint space. The episode ends
// when `duration` is spent.
#include <fruit_shape_completion/instrument/planner/evaluation.h>
#include <fruit_shape_completion/instrument/planner/roi_octree.h>
#include <fruit_shape_completion/instrument/planner/upstream_sampling.h>
#include <fruit_shape_completion/host/shape_estimator.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/rgbd_renderer.h>
#include <fruit_shape_completion/instrument/sim/robot_arm.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace planner {

// The product's estimator host, as the stand-in planner loop uses it.
using host::ShapeEstimatorHost;
using host::ViewData;
using host::ViewSource;

struct PlannerParams {
  double duration = 180.0;   // [s] simulated
  double view_cost = 2.0;    // [s] planning + capture per view
  double speed = 0.3;        // [m/s] camera travel (arm-like)
  // Upstream's samplers and utility with Planner.cfg's defaults.
  UpstreamSamplingParams sampling;
  // What a failed attempt costs: an inverse kinematics call that finds no solution, and a
  // motion plan whose goal collides with the map (MoveIt gives up on it).
  double ik_failure_cost = 0.05, plan_failure_cost = 1.0;  // [s]
  // A planning round that moved nowhere: the planner loop's next round (100 Hz) and sampling.
  double retry_cost = 0.1;  // [s]
  // Hands the estimators' extra targets to the samplers. The product's own switch is the
  // estimator's `shape_targets` parameter; this one stands for a planner built without the patch.
  bool shape_targets = true;
  // Upstream's plan_with_trolley (Planner.cfg: trolley_move_length 1000 mm,
  // trolley_time_per_segment 60 s): after each segment's time the trolley carries the arm this far
  // along the row (+x), and the planner samples in a window of the workspace around it.
  // 0: no trolley, the whole workspace.
  double trolley_move_length = 0.0;        // [m]
  double trolley_time_per_segment = 60.0;  // [s]
  double trolley_speed = 0.2;              // [m/s]
  double trolley_window_margin = 0.4;      // [m] the window reaches this far beyond a segment
  double octree_resolution = 0.01;  // [m] the ROI octree's cells
  double clearance = 0.05;     // [m] free space around the camera
  unsigned seed = 1;
  int render_threads = 1;
  bool depth_noise = true;
  // What the estimators get, as a robot's stack hands it to the plugin:
  //  kCamera: the organized camera frame (depth_image_proc) with its pose; the product's whole
  //    fruit input stage runs on it (red test, depth edges, outliers);
  //  kRoi: pointcloud_roi's PointcloudWithRoi (1 cm voxel means, red indices): what the patched
  //    upstream planner hands over when nothing else is configured;
  //  kFruitCloud: a simple_roi_detector-like node's full-resolution red points, without depth
  //    edges removed (the plugin's fruit_cloud_topic).
  enum class Input { kCamera, kRoi, kFruitCloud };
  Input input = Input::kCamera;
  double roi_leaf = 0.01;  // [m] pointcloud_roi's voxel grid
  // The paper-like profile's parts (paperProfile()); the defaults are the ideal simulation.
  bool paper_depth_noise = false;   // the paper's structured noise and blur (sim::DepthNoise::kPaper)
  bool upstream_red_test = false;   // pointcloud_roi's HSI red test (sim::RedThreshold::kUpstream)
  bool textures = false;  // for whoever builds the renderer: sim::Shading::textures (Gazebo's look)
  double estimator_period = 0.0;    // [s] > 0: estimators update on this period, not every view
  // The planner's wall time (with the estimators' insertView) adds to the clock, and a fit's
  // results reach the planner only its measured duration after it started.
  bool charge_compute_time = false;
  // The scene's arm carries the camera: only views with an inverse kinematics solution free of
  // what the map has seen occupied are sampled (as MoveIt plans in its octomap), travel takes
  // the joint-space motion time, and a move whose goal collides with the plants fails.
  bool arm = false;
  sim::ArmMotion arm_motion;
  double arm_collision_resolution = 0.01;  // [m] cells of the plants' distance field (the world)
  double arm_map_resolution = 0.02;        // [m] cells of the map's distance field (the planner's)
  // Empty if usable, else what is wrong (runEpisode refuses to start with it).
  std::string problem() const;
};

// The paper's set-up: its depth noise, an estimator refreshed every 3 s, compute time on the
// episode clock, no ground truth in planning, the UR5e on its mount with a per-plan overhead.
PlannerParams paperProfile(PlannerParams base = PlannerParams());

struct ViewRecord {
  int view = 0;
  double time = 0.0;  // [s] simulated, after this view's capture
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Evaluation old_true, se_true;  // against the enclosed volume
  Evaluation old_se, se_se;      // against the ground-truth superellipsoid volume
  Evaluation old_box;            // Old against the voxel-centre box (SceneTruth::box)
  int contour_targets = 0, shape_targets = 0;
  bool exploration = false;  // the exploration candidates were used (no ROI view above the threshold)
  double gain = 0.0;      // the best candidate's ROI-weighted gain when this view was planned
  int attempts = 0;       // moves tried (best first) before one succeeded or the list ran out
  bool to_shape_target = false;  // the move after this view went to a view of a shape target
  double wall_ms = 0.0;
  double compute_ms = 0.0;  // what the planner blocked on: wall_ms without rendering and the fit
  double fit_ms = 0.0;      // a fit started after this view (0: none); runs beside the planner
  double insert_ms = 0.0;   // the estimators' insertView of this view (what the planner waits for)
  double rss_mib = 0.0;     // the process's resident memory after this view
};

struct EpisodeResult {
  std::vector<ViewRecord> views;
  std::string message;  // why it ended early or ran empty; empty if it ran normally
  int truth_fruits = 0;
  // The fruit mask against the renderer's labels, over all pixels with a surface: red-fruit
  // pixels it missed, and other pixels it took for fruit.
  std::uint64_t mask_positives = 0, mask_false_negatives = 0;
  std::uint64_t mask_negatives = 0, mask_false_positives = 0;
  // Move attempts and those the arm could plan; why the others failed (no inverse kinematics,
  // joint limits, a goal in collision with the map or the pole).
  int sampled_views = 0, reachable_views = 0, unreachable_ik = 0, unreachable_limits = 0, unreachable_collision = 0;
  int failed_moves = 0;  // planned moves whose goal hit plants the map had not seen
  int failed_moves_shape = 0;  // of which toward views of the estimators' targets
  int moves = 0, moves_shape = 0;  // successful moves, of which toward views of their targets
  int trolley_moves = 0;
  int planning_rounds = 0, rounds_without_move = 0;
  std::vector<FruitEstimate> final_fruits;  // the estimator's scored fruits after the last view
  int dropped_views = 0;       // views that threw and were skipped
  std::string dropped_reason;  // the first one's exception
};

struct SceneTruth {
  std::vector<TruthFruit> enclosed;  // volume = enclosed volume
  std::vector<TruthFruit> se;        // volume = superellipsoid volume
  // The upstream planner evaluator's ground truth for the Old boxes: the box of the centres of
  // the fruit's voxels at the octree resolution (its midpoint as the centre). Box against box:
  // a fully seen fruit's Old box scores ~1 here, ~0.1 against the enclosed volume.
  std::vector<TruthFruit> box;
  double box_resolution = 0.0;  // [m] the cells `box` was made for (runEpisode checks it)
  // Centres of the fruits the paper does not score (not red): estimates nearer one of them
  // than any scored fruit are left out of the evaluation, neither matches nor false matches.
  std::vector<Eigen::Vector3d> not_scored;
  std::vector<FruitEstimate> scoredEstimates(std::vector<FruitEstimate> estimates) const;
};
// All three from the scene's red ground-truth fruits; `resolution` is the ROI octree's.
SceneTruth makeSceneTruth(const std::vector<sim::FruitTruth>& fruits, double resolution);

// Called after every view (e.g. to publish it) with the rendered frame and what the estimators
// were given; return false to stop the episode.
using ViewCallback = std::function<bool(const ViewRecord&, const RoiOcTree&, const sim::RgbdFrame&, const ViewData&)>;

// Scores the estimators' fruits and the ROI octree's Old boxes against the truth into *rec
// (as the paper does); returns the estimators' scored fruits.
std::vector<FruitEstimate> scoreView(const RoiOcTree& tree, const SceneTruth& truth,
                                     const std::vector<FruitEstimate>& estimates, ViewRecord* rec);

const char* toString(PlannerParams::Input input);
bool parseInput(const std::string& name, PlannerParams::Input* input);  // camera, roi, fruit-cloud

EpisodeResult runEpisode(const sim::Scene& scene, const sim::RgbdRenderer& renderer,
                         const SceneTruth& truth, ShapeEstimatorHost& host, const PlannerParams& params,
                         const ViewCallback& on_view = nullptr);

}  // namespace planner
}  // namespace fruit_shape_completion
