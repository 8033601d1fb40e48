// Simulated camera benchmark. Run: scripts/run.sh bench --benchmark_filter=Render
#include <benchmark/benchmark.h>
#include <fruit_shape_completion/instrument/sim/fruit_mask.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/rgbd_renderer.h>

#include <cstdlib>
#include <memory>

using namespace fruit_shape_completion;
using namespace fruit_shape_completion::sim;

// One 640x480 frame of scenario 1 from its start view: Embree ray casting (2 threads), shading,
// noise, then the red thresholder and the fruit and full clouds.
static void BM_RenderView(benchmark::State& state) {
  const char* env = std::getenv("FSC_SHARED_DATA");
  const std::string path = std::string(env ? env : "../shared/data") + "/scenes/scenario1_world14.yaml";
  Scene scene;
  std::string err;
  if (!loadScene(path, &scene, &err)) {
    state.SkipWithError(("needs ../shared/data (set FSC_SHARED_DATA): " + err).c_str());
    return;
  }
  std::vector<int> triangle_fruit;
  computeFruitTruth(scene, &triangle_fruit);
  const RgbdRenderer renderer(scene, triangle_fruit);
  const PinholeCamera cam = PinholeCamera::lookingAt(scene.camera_start_position, scene.camera_start_look_at);
  std::size_t fruit_points = 0;
  for (auto _ : state) {
    const RgbdFrame frame = renderer.render(cam);
    const FrameClouds clouds = cloudsFromFrame(frame, redMask(frame.rgb, frame.width, frame.height));
    fruit_points = clouds.fruit.size();
  }
  state.counters["fruit_points"] = static_cast<double>(fruit_points);
  state.counters["triangles"] = static_cast<double>(scene.triangles.size());
}
BENCHMARK(BM_RenderView)->Unit(benchmark::kMillisecond);
