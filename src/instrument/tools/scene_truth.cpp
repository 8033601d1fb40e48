// scene_truth: the ground-truth fruits of a scene.
//   scene_truth --scene FILE|procedural[:SEED] [--json] [--write-scene DIR]
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/instrument/sim/procedural_scene.h>

#include "command_line.h"
#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>

using namespace fruit_shape_completion;
using namespace fruit_shape_completion::sim;

int main(int argc, char** argv) {
  std::string spec, write_dir;
  bool json = false;
  CLI::App app("The ground-truth fruits of a scene.", "scene_truth");
  app.add_option("--scene", spec, "scene file, or procedural[:SEED]")->required();
  app.add_flag("--json", json, "one JSON object on stdout");
  app.add_option("--write-scene", write_dir, "also write the scene (OBJ + YAML) into this directory");
  if (const int done = parseCommandLine(app, argc, argv); done >= 0) return done;
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
    nlohmann::json out = {{"scene", scene.name}, {"fruits", nlohmann::json::array()}};
    for (const FruitTruth& f : fruits)
      out["fruits"].push_back({{"id", f.id},
                               {"plant", f.plant},
                               {"center", {f.center.x(), f.center.y(), f.center.z()}},
                               {"volume_m3", f.volume},
                               {"se_volume_m3", f.se_volume},
                               {"color", f.color}});
    std::cout << out.dump() << "\n";
  } else {
    std::printf("%4s %5s %28s %10s %10s %7s\n", "id", "plant", "centre [m]", "V [cm3]", "V_SE [cm3]", "colour");
    for (const auto& f : fruits)
      std::printf("%4d %5d (%8.4f,%8.4f,%8.4f) %10.1f %10.1f %7s\n", f.id, f.plant, f.center.x(), f.center.y(),
                  f.center.z(), f.volume * 1e6, f.se_volume * 1e6, f.color.c_str());
  }
  return 0;
}
