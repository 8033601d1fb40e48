#pragma once
// A procedural glasshouse that needs no files: rows of plants with a stem, branches and leaves
// that really occlude, and pepper-like fruits that are NOT superellipsoids (lobes, taper, a
// dent and a stem cap; 60-250 cm^3), mostly red, some yellow. Seeded and reproducible; it can
// write itself out as a scene file plus OBJ meshes, loadable by loadScene.
#include <fruit_shape_completion/instrument/sim/scene.h>

#include <string>

namespace fruit_shape_completion {
namespace sim {

struct ProceduralSceneParams {
  unsigned seed = 1;
  int rows = 1;
  int plants_per_row = 4;
  double plant_spacing = 0.45;  // [m] along a row
  double row_spacing = 1.0;     // [m]
  int min_fruits = 3, max_fruits = 5;  // per plant
  double yellow_fraction = 0.2;
  int leaves = 30;              // per plant
  double min_volume = 60e-6, max_volume = 250e-6;  // [m^3]
};

Scene generateProceduralScene(const ProceduralSceneParams& params = ProceduralSceneParams());

// "procedural" or "procedural:SEED" generates the default glasshouse; "procedural-row",
// "procedural-row:SEED" or "procedural-row:SEED:PLANTS" one row of PLANTS plants (default 80,
// about 320 fruits over 36 m), the camera starting at its first plant; anything else is a scene
// file path.
bool loadSceneSpec(const std::string& spec, Scene* scene, std::string* error);

// Writes DIR/scene.yaml, DIR/scene.mtl and one DIR/plant_N.obj per plant (plant frame).
bool writeSceneFiles(const Scene& scene, const std::string& dir, std::string* error);

}  // namespace sim
}  // namespace fruit_shape_completion
