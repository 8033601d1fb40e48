// run_trials: episodes of the viewpoint planner on a scene, Old (ROI octree boxes) and SE
// (superellipsoids) evaluated side by side after every view, as in the paper's tables.
//   run_trials --scene FILE|procedural[:SEED] --trials N --duration S [--seed K]
//              [--profile paper|ideal] [--red-test hsv|upstream] [--flat-colours] [--no-shape-targets] [--no-noise]
//              [--input camera|roi|fruit-cloud] [--no-depth-edges] [--input-outliers K,STD,R] [--no-veil]
//              [--velocity-scaling S] [--plan-overhead S] [--center-rim-margin M] [--out DIR] [--json] [--jobs J]
#include <fruit_shape_completion/host/superellipsoid_estimator.h>
#include <fruit_shape_completion/instrument/cloud_io.h>
#include <fruit_shape_completion/instrument/planner/viewpoint_planner.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>

#include "command_line.h"
#include <nlohmann/json.hpp>

#include <filesystem>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <tuple>


using namespace fruit_shape_completion;
using namespace fruit_shape_completion::host;
using namespace fruit_shape_completion::planner;

namespace {

const char* kSubsets[3] = {"all", "ma0", "ma50"};

const SubsetStats& subset(const Evaluation& e, int s) { return s == 0 ? e.all : (s == 1 ? e.ma0 : e.ma50); }

// The last view at or before time t (nullptr if none).
const ViewRecord* at(const EpisodeResult& r, double t) {
  const ViewRecord* last = nullptr;
  for (const auto& v : r.views)
    if (v.time <= t + 1e-9) last = &v;
  return last;
}

struct MeanStd {
  double mean = 0, std = 0;
};
MeanStd meanStd(const std::vector<double>& v) {
  MeanStd m;
  if (v.empty()) return m;
  for (double x : v) m.mean += x / v.size();
  for (double x : v) m.std += (x - m.mean) * (x - m.mean) / v.size();
  m.std = std::sqrt(m.std);
  return m;
}

// Per trial: fruits of a subset, and its centre error and accuracy where it has fruits.
struct SubsetSeries {
  std::vector<double> fruits, error, accuracy;
};
SubsetSeries series(const std::vector<const Evaluation*>& evals, int s) {
  SubsetSeries out;
  for (const Evaluation* e : evals) {
    const SubsetStats& st = subset(*e, s);
    out.fruits.push_back(st.fruits);
    if (st.fruits > 0) {
      out.error.push_back(st.center_error_cm);
      out.accuracy.push_back(st.accuracy);
    }
  }
  return out;
}

// {"all": {"fruits": {...}, "center_error_cm": {...}, "accuracy": {...}}, "ma0": ..., "ma50": ...}
nlohmann::json subsetsJson(const std::vector<const Evaluation*>& evals) {
  auto ms = [](const std::vector<double>& v) {
    const MeanStd m = meanStd(v);
    return nlohmann::json{{"mean", m.mean}, {"std", m.std}};
  };
  nlohmann::json out = nlohmann::json::object();
  for (int s = 0; s < 3; ++s) {
    const SubsetSeries v = series(evals, s);
    out[kSubsets[s]] = {{"fruits", ms(v.fruits)}, {"center_error_cm", ms(v.error)}, {"accuracy", ms(v.accuracy)}};
  }
  return out;
}

void printTable(const char* title, const std::vector<const Evaluation*>& old_e, const std::vector<const Evaluation*>& se_e) {
  std::printf("\n%s\n", title);
  std::printf("%-6s %-5s %14s %16s %16s\n", "", "", "fruits", "centre err [cm]", "volume acc");
  for (int s = 0; s < 3; ++s)
    for (int k = 0; k < (se_e.empty() ? 1 : 2); ++k) {
      const SubsetSeries v = series(k == 0 ? old_e : se_e, s);
      const MeanStd a = meanStd(v.fruits), b = meanStd(v.error), c = meanStd(v.accuracy);
      std::printf("%-6s %-5s %7.1f +- %4.1f %9.2f +- %4.2f %9.3f +- %4.3f\n", k == 0 ? kSubsets[s] : "",
                  k == 0 ? "Old" : "SE", a.mean, a.std, b.mean, b.std, c.mean, c.std);
    }
}

}  // namespace

int main(int argc, char** argv) {
  std::string spec, out;
  int trials = 1, jobs = 0;
  bool json = false;
  std::string profile = "paper", red_test;  // red_test empty: the profile's
  PlannerParams base;
  double velocity_scaling = -1, plan_overhead = -1;  // < 0: the profile's
  std::string input_name = "camera";
  SuperellipsoidEstimatorParams estimator;
  bool flat_colours = false;
  CLI::App app("Episodes of the viewpoint planner on a scene; Old (ROI octree boxes) and SE (superellipsoids)\n"
               "evaluated side by side after every view, as in the paper's tables.", "run_trials");
  app.add_option("--scene", spec, "scene file, or procedural[:SEED]")->required();
  app.add_option("--trials", trials, "episodes")->check(CLI::Range(1, 1000))->capture_default_str();
  app.add_option("--duration", base.duration, "simulated seconds per episode")
      ->check(CLI::Range(1e-3, 1e6))->capture_default_str();
  app.add_option("--seed", base.seed, "seed of the first trial (trial k: seed + k)")->capture_default_str();
  app.add_option("--out", out, "where the CSV and JSON files go (default results/<scene>-<input>-<profile>)");
  app.add_option("--jobs", jobs, "episodes at a time (0: one per core)")->check(CLI::Range(0, 256));
  app.add_option("--input", input_name,
                 "what the plugin is fed: camera (the organized cloud through the whole input stage), roi\n"
                 "(pointcloud_roi's 1 cm PointcloudWithRoi), fruit-cloud (full-resolution red points, no\n"
                 "depth-edge removal)")
      ->check(CLI::IsMember({"camera", "roi", "fruit-cloud"}))->capture_default_str();
  app.add_flag_callback("--no-depth-edges", [&] { estimator.input.drop_depth_edges = false; },
                        "keep fruit pixels at depth edges");
  std::string outliers;
  app.add_option("--input-outliers", outliers, "K,STD_MUL,RADIUS: the input stage's outlier filter on (off by default)");
  app.add_flag_callback("--no-veil", [&] { estimator.input.drop_veil_points = false; },
                        "keep the veil points of 1 cm views");
  app.add_option("--profile", profile,
                 "paper: the paper's depth noise and blur, a fit every 3 s beside the planner, compute time on\n"
                 "the clock, the scene's UR5e, textured plants, pointcloud_roi's HSI red test; ideal: flat\n"
                 "colours, i.i.d. depth noise, a free-flying camera")
      ->check(CLI::IsMember({"paper", "ideal"}))->capture_default_str();
  app.add_option("--red-test", red_test, "hsv (this simulator's) or upstream (pointcloud_roi's HSI); default: the profile's")
      ->check(CLI::IsMember({"hsv", "upstream"}));
  app.add_option("--velocity-scaling", velocity_scaling, "the arm's share of its rated joint speed (paper profile: 0.5)")
      ->check(CLI::Range(1e-3, 1.0));
  app.add_option("--plan-overhead", plan_overhead, "seconds per plan besides motion and compute (ideal: 2, paper: 1.5)")
      ->check(CLI::Range(0.0, 1e3));
  double trolley_move = -1.0, trolley_time = -1.0;
  app.add_flag_callback("--trolley", [&] { trolley_move = std::max(trolley_move, 1.0); },
                        "upstream's plan_with_trolley: every 60 s the trolley carries the arm 1 m along the row (+x), "
                        "the planner samples around it (for procedural-row scenes)");
  app.add_option("--trolley-move-length", trolley_move, "[m] the trolley's step (implies --trolley; default 1)")
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--trolley-time-per-segment", trolley_time, "[s] time per trolley position (default 60)")
      ->check(CLI::Range(1.0, 1e5));
  bool save_surfaces = false;
  app.add_flag("--save-surfaces", save_surfaces,
               "also write each trial's final fruit surface cloud (surface_K.ply; fit_cloud reads it)");
  app.add_option("--center-rim-margin", estimator.pipeline.center_rim_margin,
                 "[m] the centre prior at most this far behind the deepest seen points (negative: no limit)")
      ->capture_default_str();
  app.add_flag_callback("--no-shape-targets", [&] { estimator.shape_targets = false; },
                        "the estimator's shape_targets parameter off: it fits but hands the planner no targets");
  app.add_option("--target-settled-coverage", estimator.targets.settled_coverage,
                 "fruits seen over at least this share of their fitted surface hand over no targets")
      ->check(CLI::Range(0.0, 1.0))->capture_default_str();
  app.add_option("--targets-per-fruit", estimator.targets.per_fruit, "at most this many targets per fruit (0: all)")
      ->check(CLI::Range(0, 100000))->capture_default_str();
  app.add_option("--target-offset", estimator.targets.offset, "[m] targets this far outside the predicted surface")
      ->check(CLI::Range(0.0, 0.2))->capture_default_str();
  app.add_option("--target-view-gain", estimator.targets.view_gain,
                 "added to a sampled view's utility per fruit surface's worth of predicted surface it sees")
      ->check(CLI::Range(0.0, 100.0))->capture_default_str();
  app.add_option("--target-view-fov", estimator.targets.view_fov_deg, "[deg] the cone a view sees predicted surface in")
      ->check(CLI::Range(1.0, 179.0))->capture_default_str();
  app.add_option("--target-view-max-range", estimator.targets.view_max_range,
                 "[m] predicted surface farther from a view is not counted")
      ->check(CLI::Range(0.05, 10.0))->capture_default_str();
  app.add_option("--target-view-clearance", estimator.targets.view_clearance,
                 "[m] a view this close to the planner's mapped plant gains nothing from predicted surface; 0: no check")
      ->check(CLI::Range(0.0, ShapeTargetParams::kMaxViewClearance))->capture_default_str();
  app.add_flag_callback("--any-side", [&] { estimator.targets.view_side = false; },
                        "hand over no viewing directions: the planner views shape targets from any side");
  app.add_flag_callback("--no-noise", [&] { base.depth_noise = false; }, "noise-free depth");
  app.add_flag("--flat-colours", flat_colours, "the scene files' flat colours instead of the textures");
  app.add_flag("--json", json, "print results.json to stdout");
  if (const int done = parseCommandLine(app, argc, argv); done >= 0) return done;
  if (!outliers.empty()) {
    auto& o = estimator.input.outliers;
    estimator.input.remove_outliers = true;
    char rest = 0;
    if (std::sscanf(outliers.c_str(), "%d,%lf,%lf%c", &o.k, &o.std_mul, &o.search_radius, &rest) != 3) {
      std::cerr << "run_trials: --input-outliers takes K,STD_MUL,RADIUS (e.g. 5,1.0,0.005), not '" << outliers << "'\n";
      return 2;
    }
  }
  parseInput(input_name, &base.input);
  if (profile == "paper") {
    base = paperProfile(base);
  } else if (profile != "ideal") {
    std::cerr << "run_trials: --profile must be ideal or paper\n";
    return 2;
  }
  if (!red_test.empty() && red_test != "hsv" && red_test != "upstream") {
    std::cerr << "run_trials: --red-test must be hsv or upstream\n";
    return 2;
  }
  if (red_test == "upstream") base.upstream_red_test = true;
  if (red_test == "hsv") base.upstream_red_test = false;
  if (flat_colours) base.textures = false;
  red_test = base.upstream_red_test ? "upstream" : "hsv";
  if (trolley_move > 0.0 || trolley_time > 0.0) base.trolley_move_length = trolley_move > 0.0 ? trolley_move : 1.0;
  if (trolley_time > 0.0) base.trolley_time_per_segment = trolley_time;
  if (velocity_scaling >= 0) base.arm_motion.velocity_scaling = base.arm_motion.acceleration_scaling = velocity_scaling;
  if (plan_overhead >= 0) base.view_cost = plan_overhead;
  try {
    estimator.input.validate();
    estimator.pipeline.validate();
  } catch (const std::invalid_argument& e) {
    std::cerr << "run_trials: " << e.what() << "\n";
    return 2;
  }
  if (const std::string bad = base.problem(); !bad.empty()) {
    std::cerr << "run_trials: " << bad << "\n";
    return 2;
  }
  sim::Scene scene;
  std::string err;
  if (!sim::loadSceneSpec(spec, &scene, &err)) {
    std::cerr << "run_trials: " << err << "\n";
    return 1;
  }
  std::vector<int> triangle_fruit;
  const auto fruits = sim::computeFruitTruth(scene, &triangle_fruit);
  const SceneTruth truth = makeSceneTruth(fruits, base.octree_resolution);
  sim::Shading shading;
  shading.textures = base.textures;
  const sim::RgbdRenderer renderer(scene, triangle_fruit, shading);
  if (out.empty()) {
    std::string stem = scene.name;
    for (char& c : stem)
      if (c == '/' || c == ':' || c == ' ') c = '_';
    out = "results/" + stem + "-" + input_name + "-" + profile;
  }
  std::error_code mkdir_error;
  std::filesystem::create_directories(out, mkdir_error);

  if (jobs <= 0) jobs = std::max(1u, std::thread::hardware_concurrency());
  jobs = std::min(jobs, trials);
  std::vector<EpisodeResult> results(trials);
  std::vector<double> wall(trials, 0.0);
  // Per trial and view, the work of the update started after it (fits, kept fits, clusters
  // examined; -1 without an update): what an update time is made of.
  std::vector<std::vector<std::array<int, 3>>> work(trials);
  std::atomic<int> next{0};
  std::mutex log;
  auto worker = [&]() {
    for (int k = next++; k < trials; k = next++) {
      PlannerParams p = base;
      p.seed = base.seed + static_cast<unsigned>(k);
      p.render_threads = jobs == 1 ? 2 : 1;
      ShapeEstimatorHost host;
      auto owned = std::make_unique<SuperellipsoidEstimator>(estimator);
      const SuperellipsoidEstimator* superellipsoids = owned.get();
      host.add(std::move(owned));
      const auto t0 = std::chrono::steady_clock::now();
      auto probe = [&work, k, superellipsoids](const ViewRecord& rec, const RoiOcTree&, const sim::RgbdFrame&,
                                               const ViewData&) {
        const PipelineStats s = superellipsoids->lastPipelineStats();
        work[k].push_back(rec.fit_ms > 0.0 ? std::array<int, 3>{s.fitted, s.kept, s.clusters}
                                           : std::array<int, 3>{-1, -1, -1});
        return true;
      };
      results[k] = runEpisode(scene, renderer, truth, host, p, probe);
      if (save_surfaces) {
        std::string error;
        if (!writePly(out + "/surface_" + std::to_string(k) + ".ply", superellipsoids->surface(), {}, &error))
          std::cerr << "run_trials: " << error << "\n";
      }
      wall[k] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::lock_guard<std::mutex> lock(log);
      std::cerr << "run_trials: trial " << k << ": " << results[k].views.size() << " views, " << wall[k]
                << " s wall" << (results[k].message.empty() ? "" : " (" + results[k].message + ")") << "\n";
      if (results[k].dropped_views > 0)
        std::cerr << "run_trials: trial " << k << ": " << results[k].dropped_views
                  << " views dropped, the first: " << results[k].dropped_reason << "\n";
    }
  };
  std::vector<std::thread> pool;
  for (int j = 1; j < jobs; ++j) pool.emplace_back(worker);
  worker();
  for (auto& th : pool) th.join();

  // Per-trial CSV: one row per view.
  for (int k = 0; k < trials; ++k) {
    std::ofstream csv(out + "/trial_" + std::to_string(k) + ".csv");
    csv << "view,time_s,x,y,z,exploration,gain,attempts,to_shape_target,contour_targets,shape_targets,wall_ms,compute_ms,insert_ms,fit_ms,rss_mib";
    for (const char* est : {"old", "se", "old_box"})
      for (const char* s : kSubsets) csv << ',' << est << '_' << s << "_fruits," << est << '_' << s << "_center_cm," << est << '_' << s << "_accuracy";
    csv << ",fits,kept_fits,clusters\n";
    for (std::size_t i = 0; i < results[k].views.size(); ++i) {
      const ViewRecord& v = results[k].views[i];
      csv << v.view << ',' << v.time << ',' << v.position.x() << ',' << v.position.y() << ',' << v.position.z() << ','
          << v.exploration << ',' << v.gain << ',' << v.attempts << ',' << v.to_shape_target << ',' << v.contour_targets << ',' << v.shape_targets << ',' << v.wall_ms << ',' << v.compute_ms << ',' << v.insert_ms << ',' << v.fit_ms << ',' << v.rss_mib;
      for (const Evaluation* e : {&v.old_true, &v.se_true, &v.old_box})
        for (int s = 0; s < 3; ++s)
          csv << ',' << subset(*e, s).fruits << ',' << subset(*e, s).center_error_cm << ',' << subset(*e, s).accuracy;
      const std::array<int, 3> w = i < work[k].size() ? work[k][i] : std::array<int, 3>{-1, -1, -1};
      csv << ',' << w[0] << ',' << w[1] << ',' << w[2] << '\n';
    }
  }

  // The scene's scored fruits, and per trial the final SE fruits with their nearest one.
  {
    std::ofstream t(out + "/truth.csv");
    t << "truth,x,y,z,volume_cm3\n";
    for (std::size_t i = 0; i < truth.enclosed.size(); ++i)
      t << i << ',' << truth.enclosed[i].center.x() << ',' << truth.enclosed[i].center.y() << ','
        << truth.enclosed[i].center.z() << ',' << truth.enclosed[i].volume * 1e6 << '\n';
  }
  for (int k = 0; k < trials; ++k) {
    std::ofstream f(out + "/final_fruits_" + std::to_string(k) + ".csv");
    // seen_share, rms_mm, min_axis_mm, log_volume_spread and views are what the volume interval is
    // made from (the centre radius: seen_share, rms_mm and min_axis_mm).
    f << "id,x,y,z,volume_cm3,volume_ci90_lo_cm3,volume_ci90_hi_cm3,points,nearest_truth,distance_cm,seen_share,rms_mm,"
         "min_axis_mm,center_r90_cm,log_volume_spread,views\n";
    for (const auto& e : results[k].final_fruits) {
      const Superellipsoid fitted = e.fittedShape();  // the axis bound is the fit's own
      int nearest = -1;
      double best = 1e300;
      for (std::size_t i = 0; i < truth.enclosed.size(); ++i) {
        const double d = (truth.enclosed[i].center - e.center()).norm();
        if (d < best) best = d, nearest = static_cast<int>(i);
      }
      f << e.id << ',' << e.center().x() << ',' << e.center().y() << ',' << e.center().z() << ',' << e.volume * 1e6
        << ',' << e.volume_lo * 1e6 << ',' << e.volume_hi * 1e6 << ',' << e.n_points << ',' << nearest << ','
        << (nearest >= 0 ? best * 100 : -1) << ',' << e.seen_share << ','
        << e.rms * 1e3 << ',' << 1e3 * std::min({fitted.a, fitted.b, fitted.c}) << ',' << e.center_r90 * 1e2
        << ',' << e.log_volume_spread << ',' << e.views << '\n';
    }
  }

  static const Evaluation kEmpty;
  auto collect = [&](double t, Evaluation ViewRecord::*field) {
    std::vector<const Evaluation*> v;
    for (const auto& r : results) {
      const ViewRecord* rec = at(r, t);
      v.push_back(rec ? &(rec->*field) : &kEmpty);
    }
    return v;
  };
  std::vector<double> views_per, reachable, failed_per, attempts_per, idle_per, failed_shape_per, moves_per, moves_shape_per;
  long sampled = 0, ik = 0, limits = 0, collision = 0, failed_moves = 0;
  for (const auto& r : results) {
    views_per.push_back(r.views.size());
    failed_per.push_back(r.failed_moves);
    attempts_per.push_back(r.sampled_views);
    idle_per.push_back(r.rounds_without_move);
    failed_shape_per.push_back(r.failed_moves_shape);
    moves_per.push_back(r.moves);
    moves_shape_per.push_back(r.moves_shape);
    if (r.sampled_views > 0) reachable.push_back(double(r.reachable_views) / r.sampled_views);
    sampled += r.sampled_views;
    ik += r.unreachable_ik;
    limits += r.unreachable_limits;
    collision += r.unreachable_collision;
    failed_moves += r.failed_moves;
  }
  const MeanStd reach = meanStd(reachable);
  std::ofstream js(out + "/results.json");
  nlohmann::json body = {
      {"scene", scene.name}, {"profile", profile}, {"red_test", red_test}, {"textures", base.textures},
      {"trials", trials}, {"duration_s", base.duration}, {"shape_targets", estimator.shape_targets},
      {"center_rim_margin_m", estimator.pipeline.center_rim_margin},
      {"targets", {{"settled_coverage", estimator.targets.settled_coverage}, {"per_fruit", estimator.targets.per_fruit},
                   {"offset_m", estimator.targets.offset},
                   {"view_side", estimator.targets.view_side},
                   {"view_gain", estimator.targets.view_gain}, {"view_fov_deg", estimator.targets.view_fov_deg},
                   {"view_max_range_m", estimator.targets.view_max_range},
                   {"view_clearance_m", estimator.targets.view_clearance}}},
      {"planner", "upstream"},
      {"input", input_name},
      {"input_stage", {{"depth_edges", estimator.input.drop_depth_edges}, {"outliers", estimator.input.remove_outliers},
                       {"veil", estimator.input.drop_veil_points}}},
      {"truth_fruits", truth.enclosed.size()}, {"unscored_fruits", truth.not_scored.size()},
      {"views_per_trial", meanStd(views_per).mean}, {"wall_s_per_trial", meanStd(wall).mean},
      {"robot", base.arm ? scene.robot.describe() : "none (free camera)"},
      {"velocity_scaling", base.arm ? base.arm_motion.velocity_scaling : 0.0}, {"plan_overhead_s", base.view_cost}};
  if (base.arm) {
    body["reachable_fraction"] = {{"mean", reach.mean}, {"std", reach.std}};
    body["unreachable"] = {{"sampled", sampled}, {"no_inverse", ik}, {"joint_limits", limits}, {"collision", collision}};
  }
  body["failed_moves_per_trial"] = double(failed_moves) / trials;
  body["trolley"] = {{"move_length_m", base.trolley_move_length}, {"time_per_segment_s", base.trolley_time_per_segment}};
  {
    nlohmann::json moves = nlohmann::json::array();
    for (const auto& r : results) moves.push_back(r.trolley_moves);
    body["trolley_moves"] = moves;
  }
  body["failed_moves"] = failed_per;                // per trial: moves executed into unseen plants
  body["move_attempts"] = attempts_per;             // per trial: candidates tried best first
  body["rounds_without_move"] = idle_per;           // per trial: planning rounds whose every attempt failed
  body["failed_moves_shape"] = failed_shape_per;    // per trial: failed moves toward views of shape targets
  body["moves"] = moves_per;                        // per trial: successful moves
  body["moves_shape"] = moves_shape_per;            // per trial: of which toward views of shape targets
  for (const auto& [label, t] : {std::make_pair("final", base.duration), std::make_pair("at_60s", 60.0),
                                std::make_pair("at_120s", 120.0)}) {
    body[label] = {{"old", subsetsJson(collect(t, &ViewRecord::old_true))},
                   {"se", subsetsJson(collect(t, &ViewRecord::se_true))},
                   {"against_se_truth",
                    {{"old", subsetsJson(collect(t, &ViewRecord::old_se))}, {"se", subsetsJson(collect(t, &ViewRecord::se_se))}}},
                   {"against_box_truth", {{"old", subsetsJson(collect(t, &ViewRecord::old_box))}}}};
  }
  std::string messages;
  for (const auto& r : results)
    if (!r.message.empty() && messages.find(r.message) == std::string::npos) messages += (messages.empty() ? "" : "; ") + r.message;
  int dropped = 0;
  std::vector<double> fn_rate, fp_rate;  // per episode
  for (const auto& r : results) {
    dropped += r.dropped_views;
    if (r.mask_positives > 0) fn_rate.push_back(double(r.mask_false_negatives) / double(r.mask_positives));
    if (r.mask_negatives > 0) fp_rate.push_back(double(r.mask_false_positives) / double(r.mask_negatives));
  }
  const MeanStd fn = meanStd(fn_rate), fp = meanStd(fp_rate);
  // The 90 % volume intervals and centre radii of the final fruits against the truth: each fruit
  // matched to the nearest unmatched true fruit within 3 cm (nearest pairs first).
  {
    long inside = 0, matched = 0, center_inside = 0;
    std::vector<double> half_widths, radii;
    for (const auto& r : results) {
      std::vector<std::tuple<double, std::size_t, std::size_t>> pairs;
      for (std::size_t e = 0; e < r.final_fruits.size(); ++e)
        for (std::size_t i = 0; i < truth.enclosed.size(); ++i) {
          const double d = (truth.enclosed[i].center - r.final_fruits[e].center()).norm();
          if (d <= 0.03) pairs.emplace_back(d, e, i);
        }
      std::sort(pairs.begin(), pairs.end());
      std::vector<char> used_e(r.final_fruits.size(), 0), used_t(truth.enclosed.size(), 0);
      for (const auto& [d, e, i] : pairs) {
        if (used_e[e] || used_t[i]) continue;
        used_e[e] = used_t[i] = 1;
        const FruitEstimate& f = r.final_fruits[e];
        ++matched;
        inside += truth.enclosed[i].volume >= f.volume_lo && truth.enclosed[i].volume <= f.volume_hi;
        if (f.volume > 0) half_widths.push_back(0.5 * (f.volume_hi - f.volume_lo) / f.volume);
        center_inside += d <= f.center_r90;
        radii.push_back(f.center_r90);
      }
    }
    std::sort(half_widths.begin(), half_widths.end());
    std::sort(radii.begin(), radii.end());
    body["center_r90"] = {{"matched_fruits", matched},
                          {"truth_inside", matched ? double(center_inside) / matched : 0.0},
                          {"median_radius_m", radii.empty() ? 0.0 : radii[radii.size() / 2]}};
    body["volume_ci90"] = {{"matched_fruits", matched},
                           {"truth_inside", matched ? double(inside) / matched : 0.0},
                           {"median_relative_half_width", half_widths.empty() ? 0.0 : half_widths[half_widths.size() / 2]}};
  }
  body["mask_false_negative_rate"] = {{"mean", fn.mean}, {"std", fn.std}};
  body["mask_false_positive_rate"] = {{"mean", fp.mean}, {"std", fp.std}};
  body["dropped_views"] = dropped;
  body["messages"] = messages;
  const std::string text = body.dump() + "\n";
  js << text;
  if (!js) {
    std::cerr << "run_trials: cannot write " << out << "/results.json\n";
    return 1;
  }
  if (json) {
    std::cout << text;
  } else {
    std::printf("%s: %zu red ground-truth fruits scored (%zu of other colours not), %d trials of %.0f s (simulated), shape targets %s, %.1f views and %.1f s wall per trial\n",
                scene.name.c_str(), truth.enclosed.size(), truth.not_scored.size(), trials, base.duration, estimator.shape_targets ? "on" : "off",
                meanStd(views_per).mean, meanStd(wall).mean);
    if (!messages.empty()) std::printf("note: %s\n", messages.c_str());
    if (base.arm && sampled > 0)
      std::printf("arm: %s; %.1f +- %.1f %% of sampled views reachable (of %ld unreachable: %.0f %% no inverse kinematics, "
                  "%.0f %% joint limits, %.0f %% collision with the map); %.1f moves per trial failed on plants the map had not seen\n",
                  scene.robot.describe().c_str(), 100 * reach.mean, 100 * reach.std,
                  ik + limits + collision, 100.0 * ik / std::max(1L, ik + limits + collision),
                  100.0 * limits / std::max(1L, ik + limits + collision), 100.0 * collision / std::max(1L, ik + limits + collision),
                  double(failed_moves) / trials);
    std::printf("fruit mask against the labels, per episode: %.2f +- %.2f %% of red-fruit pixels missed, "
                "%.3f +- %.3f %% of other pixels taken for fruit\n", 100 * fn.mean, 100 * fn.std, 100 * fp.mean, 100 * fp.std);
    printTable("after the full duration, against the enclosed (true) volume:", collect(base.duration, &ViewRecord::old_true),
               collect(base.duration, &ViewRecord::se_true));
    printTable("against the paper-style ground-truth superellipsoid volume:", collect(base.duration, &ViewRecord::old_se),
               collect(base.duration, &ViewRecord::se_se));
    printTable("Old as the upstream evaluator scores it (box against the fruit's voxel-centre box):",
               collect(base.duration, &ViewRecord::old_box), {});
    std::printf("\nwritten: %s/results.json, %s/trial_*.csv (per view), %s/final_fruits_*.csv (SE fruits at the end), %s/truth.csv\n",
                out.c_str(), out.c_str(), out.c_str(), out.c_str());
  }
  return 0;
}
