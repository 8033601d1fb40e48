// libFuzzer target: the scene YAML reader (meshes are read by Assimp; a small valid one is
// offered as leaf.obj beside the scene so fuzzed scenes can reach the placement checks).
#include "fuzz_input_file.h"

#include <fruit_shape_completion/instrument/sim/scene.h>

#include <cmath>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool meshes = [] {
    std::ofstream(fuzz::scratchDir() + "/leaf.obj") << "mtllib leaf.mtl\nusemtl leaf\nv 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n";
    std::ofstream(fuzz::scratchDir() + "/leaf.mtl") << "newmtl leaf\nKd 0 1 0\n";
    return true;
  }();
  (void)meshes;
  const std::string path = fuzz::writeInput(data, size, "scene.yaml");
  fruit_shape_completion::sim::Scene scene;
  std::string error;
  if (!fruit_shape_completion::sim::loadScene(path, &scene, &error)) {
    if (error.empty()) std::abort();
    return 0;
  }
  // An accepted scene is safe to hand to the ray tracer.
  for (const auto& v : scene.vertices)
    if (!v.allFinite() || v.cwiseAbs().maxCoeff() > fruit_shape_completion::kMaxCoordinate) std::abort();
  for (const auto& p : scene.plants)
    if (!std::isfinite(p.yaw)) std::abort();
  return 0;
}
