// map_tool: inspects a saved TSDF fruit map: its size, its surface (PLY points or mesh) and the
// superellipsoids fitted to it.
//   map_tool --map FILE.tsdf [--surface-out F.ply] [--mesh-out F.ply] [--fit] [--json]
//            [--export-fruits FILE.csv|FILE.json]
#include <fruit_shape_completion/instrument/cloud_io.h>
#include <fruit_shape_completion/fruit_report.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/fruit_sightings.h>
#include <fruit_shape_completion/tsdf_surface.h>

#include "command_line.h"

#include <iostream>
#include <map>

#include "fruit_text.h"

using namespace fruit_shape_completion;

int main(int argc, char** argv) {
  std::string map_file, surface_out, mesh_out, export_out;
  bool fit = false, json = false;
  TsdfMapParams map_params;
  CLI::App app("Inspects a saved TSDF fruit map: its size, its surface and the superellipsoids fitted to it.",
               "map_tool");
  app.add_option("--map", map_file, "FILE.tsdf (save_map, demo_mapping --save-map)")->required();
  app.add_option("--surface-out", surface_out, "PLY of the surface points");
  app.add_option("--mesh-out", mesh_out, "PLY mesh of the surface (marching cubes)");
  app.add_flag("--fit", fit, "fit the fruits and list them");
  app.add_flag("--json", json, "one JSON object on stdout");
  app.add_option("--export-fruits", export_out,
                 "the fitted fruits as the plugin's export_fruits writes them (.csv or .json); views,\n"
                 "first_seen and last_seen from the counts save_map keeps with the map (empty for a\n"
                 "file without them, as demo_mapping --save-map writes)");
  app.add_option("--memory-budget-mb", map_params.memory_budget_mb,
                 "refuse maps needing more memory than this (a plugin with a larger memory_budget_mb saves them)")
      ->check(CLI::PositiveNumber);
  if (const int done = parseCommandLine(app, argc, argv); done >= 0) return done;
  TsdfMap map(map_params);
  std::string err, rest;
  if (!map.load(map_file, &err, &rest)) {
    std::cerr << "map_tool: " << err << "\n";
    return 1;
  }
  std::vector<CarriedSightings> carried;
  if (!readCarriedSightings(rest, &carried, &err)) {
    std::cerr << "map_tool: warning: " << map_file << ": " << err << "; the saved views are not used\n";
    carried.clear();
  }
  const PointList surface = extractSurfacePoints(map);
  std::cerr << "map_tool: " << map.blockCount() << " blocks, " << map.observedVoxelCount()
            << " observed voxels, " << surface.size() << " surface points, voxel "
            << map.voxelSize() << " m\n";
  if (!surface_out.empty() && !writePly(surface_out, surface, {}, &err)) {
    std::cerr << "map_tool: " << err << "\n";
    return 1;
  }
  if (!mesh_out.empty() && !extractSurfaceMesh(map).writePly(mesh_out, &err)) {
    std::cerr << "map_tool: " << err << "\n";
    return 1;
  }
  std::vector<FruitEstimate> fruits;
  std::map<int, FruitSightings> seen;
  if (fit || !export_out.empty()) {
    FruitShapePipeline pipeline;
    fruits = pipeline.update(surface);
    if (!carried.empty()) {
      // As the plugin after load_map: each fruit counts the saved views of the record it claims
      // (one without reads as seen in one), and its interval is that count's.
      FruitSightingLog log;
      log.carryOver(std::move(carried));
      log.update(fruits);
      log.countViews(&fruits);
      seen = log.sightings();
    }
  }
  if (!export_out.empty()) {
    if (!writeFruitReport(export_out, fruits, seen, &err)) {
      std::cerr << "map_tool: " << err << "\n";
      return 1;
    }
    int accepted = 0;
    for (const auto& f : fruits) accepted += f.accepted ? 1 : 0;
    std::cerr << "map_tool: " << accepted << " fruits written to " << export_out << "\n";
  }
  if (json) {
    nlohmann::json out = {{"blocks", map.blockCount()},        {"observed_voxels", map.observedVoxelCount()},
                          {"surface_points", surface.size()},   {"memory_bytes", map.memoryBytes()}};
    // Without --fit (or --export-fruits) nothing was fitted: no "fruits" key, not an empty list
    // that would read as a map without fruits.
    if (fit || !export_out.empty()) {
      out["fruits"] = nlohmann::json::array();
      out["units"] = {{"center", "m"}, {"a, b, c", "m"}, {"rpy", "rad"}, {"volume", "m^3"}};
      for (const auto& f : fruits) out["fruits"].push_back(fruitJson(f));
    }
    std::cout << out.dump() << "\n";
  } else if (fit) {
    printFruitTable(std::cout, fruits);
  }
  return 0;
}
