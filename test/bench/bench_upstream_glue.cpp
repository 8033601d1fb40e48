// The per-view update through the upstream-shaped glue, as the patched roi_viewpoint_planner
// runs it: a PointcloudWithRoi as pointcloud_roi builds it (the coloured cloud at 1 cm, the red
// voxels' indices, the cloud in the map frame, the camera pose as transform) read by
// ros_io::toRoiView, then insert and update of the superellipsoid estimator. The view sequence
// is a seeded scenario-2 episode (120 s) with depth noise. Needs no ROS master.
// Run: scripts/run.sh bench --benchmark_filter=UpstreamGlue
#include <benchmark/benchmark.h>
#include <fruit_shape_completion/host/superellipsoid_estimator.h>
#include <fruit_shape_completion/ros/fruit_publisher.h>
#include <fruit_shape_completion/ros/roi_planner_shape_estimators.h>

#include <tf2_eigen/tf2_eigen.h>

#include "bench_episode.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <map>
#include <random>

using namespace fruit_shape_completion;

namespace {

struct RoiMessage {
  sensor_msgs::PointCloud2 cloud;
  std::vector<std::int32_t> roi_indices;
  geometry_msgs::Transform transform;
};

// One list of messages per recorded episode.
const std::vector<std::vector<RoiMessage>>& roiMessages() {
  static const std::vector<std::vector<RoiMessage>> episodes = [] {
    std::vector<std::vector<RoiMessage>> all_episodes;
    for (unsigned seed : bench::kEpisodeSeeds) {
      std::vector<RoiMessage> out;
      bench::recordEpisode(planner::PlannerParams::Input::kRoi, seed, [&](const PinholeCamera&, const host::ViewData& view) {
        RoiMessage m;
        const PointList& all = view.full_cloud;
        m.cloud = ros_io::toCloud(all, "world", ros::Time(0));
        std::map<std::array<double, 3>, std::int32_t> index;
        for (std::size_t i = 0; i < all.size(); ++i) index[{all[i].x(), all[i].y(), all[i].z()}] = static_cast<std::int32_t>(i);
        for (const auto& p : view.fruit_cloud) m.roi_indices.push_back(index.at({p.x(), p.y(), p.z()}));
        m.transform = tf2::eigenToTransform(view.sensor_pose).transform;
        out.push_back(std::move(m));
      });
      all_episodes.push_back(std::move(out));
    }
    return all_episodes;
  }();
  return episodes;
}

}  // namespace

static void BM_PerViewUpdateUpstreamGlue(benchmark::State& state) {
  const auto& episodes = roiMessages();
  if (episodes.empty() || episodes.front().empty()) {
    state.SkipWithError("the recorded episode has no views");
    return;
  }
  std::vector<double> per_view_ms, read_ms;
  std::size_t fruits = 0, points = 0;
  for (auto _ : state) {
    fruits = 0;
    for (const auto& messages : episodes) {
      host::SuperellipsoidEstimator estimator;
      for (const auto& m : messages) {
        const auto t0 = std::chrono::steady_clock::now();
        ros_io::RoiView view;
        std::string error;
        if (!ros_io::toRoiView(m.cloud, m.roi_indices, m.transform, "world", &view, &error)) {
          state.SkipWithError(error.c_str());
          return;
        }
        const auto t1 = std::chrono::steady_clock::now();
        estimator.insertView({view.fruit, view.all, view.sensor_pose, 0.0, host::ViewSource::kRoiCloud});
        estimator.update();
        const auto t2 = std::chrono::steady_clock::now();
        read_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
        per_view_ms.push_back(std::chrono::duration<double, std::milli>(t2 - t0).count());
        points += view.fruit.size();
      }
      fruits += estimator.fruits().size();
    }
  }
  state.counters["episodes"] = static_cast<double>(episodes.size());
  state.counters["views"] = static_cast<double>(per_view_ms.size() / state.iterations());
  state.counters["median_ms"] = bench::quantile(per_view_ms, 0.5);
  state.counters["p95_ms"] = bench::quantile(per_view_ms, 0.95);
  state.counters["read_median_ms"] = bench::quantile(read_ms, 0.5);
  state.counters["fruit_points"] = static_cast<double>(points) / static_cast<double>(per_view_ms.size());
  state.counters["fruits"] = static_cast<double>(fruits);
}
BENCHMARK(BM_PerViewUpdateUpstreamGlue)->Unit(benchmark::kMillisecond)->Iterations(3);

// What the patched planner blocks on: a 1 cm PointcloudWithRoi read and handed to the plugin's
// host (veil filter; the worker integrates) while the estimator's worker updates, each view
// meeting the running update of the one before (bench::Pace). Counters over all views.
static void BM_InsertViewLatencyRoiCloud(benchmark::State& state) {
  const auto& episodes = roiMessages();
  bench::insertViewLatency(state, bench::episodeSizes(episodes), bench::Pace::kMeetsUpdate, [&](host::ShapeEstimatorHost& host, std::size_t e, std::size_t k) {
    const RoiMessage& m = episodes[e][k];
    ros_io::RoiView view;
    std::string error;
    if (ros_io::toRoiView(m.cloud, m.roi_indices, m.transform, "world", &view, &error))
      host.onView({view.fruit, view.all, view.sensor_pose, 0.0, host::ViewSource::kRoiCloud});
    return error;
  });
}
BENCHMARK(BM_InsertViewLatencyRoiCloud)->Name("BM_InsertViewLatency/pointcloud_with_roi_1cm")
    ->Unit(benchmark::kMillisecond)->Iterations(3);

// The view clearance the patched planner checks for every sampled view that would gain from
// predicted surface (shape_view_gain.h, occupiedCellsNear): the planner's 1 cm octree after a
// 120 s scenario-2 episode, cameras 0.3-0.5 m from its occupied cells in random directions;
// arg: the clearance [cm] (default 15, the largest allowed 50). Time per call.
static void BM_ViewClearance(benchmark::State& state) {
  static const std::unique_ptr<planner::RoiOcTree> tree = [] {
    std::unique_ptr<planner::RoiOcTree> kept;
    bench::recordEpisode(
        planner::PlannerParams::Input::kRoi, bench::kEpisodeSeeds[0], [](const PinholeCamera&, const host::ViewData&) {},
        [&](const planner::RoiOcTree& t) { kept = std::make_unique<planner::RoiOcTree>(t); });
    return kept;
  }();
  if (!tree) {
    state.SkipWithError("the episode took no view");
    return;
  }
  static const std::vector<Eigen::Vector3d> cameras = [] {
    std::vector<Eigen::Vector3d> out;
    std::mt19937 rng(11);
    std::normal_distribution<double> g(0.0, 1.0);
    std::uniform_real_distribution<double> u(0.3, 0.5);
    std::vector<Eigen::Vector3d> occupied;
    for (auto it = tree->begin_leafs(), end = tree->end_leafs(); it != end; ++it)
      if (tree->isNodeOccupied(*it)) occupied.emplace_back(it.getX(), it.getY(), it.getZ());
    if (occupied.empty()) return out;
    std::uniform_int_distribution<std::size_t> pick(0, occupied.size() - 1);
    for (int i = 0; i < 500; ++i) {
      const Eigen::Vector3d d = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
      out.push_back(occupied[pick(rng)] + u(rng) * d);
    }
    return out;
  }();
  if (cameras.empty()) {
    state.SkipWithError("the episode's map holds no occupied cell");
    return;
  }
  const double radius = 0.01 * static_cast<double>(state.range(0));
  const OccupiedNear near = occupiedCellsNear(*tree);
  std::size_t i = 0, crowded = 0, calls = 0;
  for (auto _ : state) {
    crowded += near(cameras[i], radius) ? 1 : 0;
    i = (i + 1) % cameras.size();
    ++calls;
  }
  state.counters["crowded_share"] = static_cast<double>(crowded) / static_cast<double>(std::max<std::size_t>(1, calls));
}
BENCHMARK(BM_ViewClearance)->Arg(15)->Arg(50)->Unit(benchmark::kMicrosecond);
