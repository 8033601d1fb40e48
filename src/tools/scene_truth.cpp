// scene_truth: the ground-truth fruits of a scene.
//   scene_truth --scene FILE|procedural[:SEED] [--json] [--write-scene DIR]
#include <fruit_shape_completion/sim/fruit_truth.h>
#include <fruit_shape_completion/sim/procedural_scene.h>

#include <cstdio>
#include <cstring>
#include <iostream>

#include "fruit_report.h"

using namespace fruit_shape_completion;
using namespace fruit_shape_completion::sim;

int main(int argc, char** argv) {
  std::string spec, write_dir;
  bool json = false;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--scene") && i + 1 < argc) spec = argv[++i];
    else if (!std::strcmp(argv[i], "--json")) json = true;
    else if (!std::strcmp(argv[i], "--write-scene") && i + 1 < argc) write_dir = argv[++i];
    else {
      std::cerr << "usage: scene_truth --scene FILE|procedural[:SEED] [--json] [--write-scene DIR]\n";
      return 2;
    }
  }
  if (spec.empty()) {
    std::cerr << "scene_truth: --scene is required\n";
    return 2;
  }
  Scene scene;
  std::string err;
  if (!loadSceneSpec(spec, &scene, &err)) {
    std::cerr << "scene_truth: " << err << "\n";
    return 1;
  }
  if (!write_dir.empty() && !writeSceneFiles(scene, write_dir, &err)) {
    std::cerr << "scene_truth: " << err << "\n";
    return 1;
  }
  const std::vector<FruitTruth> fruits = computeFruitTruth(scene);
  std::cerr << "scene_truth: " << scene.name << ": " << scene.plants.size() << " plants, "
            << scene.triangles.size() << " triangles, " << fruits.size() << " fruits\n";
  if (json) {
    std::cout << "{\"scene\": " << jsonString(scene.name) << ", \"fruits\": [";
    for (std::size_t i = 0; i < fruits.size(); ++i) {
      const FruitTruth& f = fruits[i];
      std::cout << (i ? ", " : "") << "{\"id\": " << f.id << ", \"plant\": " << f.plant << ", \"center\": ["
                << jsonNumber(f.center.x()) << ", " << jsonNumber(f.center.y()) << ", " << jsonNumber(f.center.z())
                << "], \"volume_m3\": " << jsonNumber(f.volume) << ", \"se_volume_m3\": " << jsonNumber(f.se_volume)
                << ", \"color\": " << jsonString(f.color) << "}";
    }
    std::cout << "]}\n";
  } else {
    std::printf("%4s %5s %28s %10s %10s %7s\n", "id", "plant", "centre [m]", "V [cm3]", "V_SE [cm3]", "colour");
    for (const auto& f : fruits)
      std::printf("%4d %5d (%8.4f,%8.4f,%8.4f) %10.1f %10.1f %7s\n", f.id, f.plant, f.center.x(), f.center.y(),
                  f.center.z(), f.volume * 1e6, f.se_volume * 1e6, f.color.c_str());
  }
  return 0;
}
