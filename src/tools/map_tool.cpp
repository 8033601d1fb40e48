// map_tool: inspects a saved TSDF fruit map: its size, its surface (PLY points or mesh) and the
// superellipsoids fitted to it.
//   map_tool --map FILE.tsdf [--surface-out F.ply] [--mesh-out F.ply] [--fit] [--json]
#include <fruit_shape_completion/cloud_io.h>
#include <fruit_shape_completion/fruit_shape_pipeline.h>
#include <fruit_shape_completion/tsdf_surface.h>

#include <cstring>
#include <iostream>

#include "fruit_report.h"

using namespace fruit_shape_completion;

namespace {
int usage(const std::string& why) {
  if (!why.empty()) std::cerr << "map_tool: " << why << "\n";
  std::cerr << "usage: map_tool --map FILE.tsdf [--surface-out F.ply] [--mesh-out F.ply] [--fit] [--json]\n";
  return 2;
}
}  // namespace

int main(int argc, char** argv) {
  std::string map_file, surface_out, mesh_out;
  bool fit = false, json = false;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--map") && i + 1 < argc) map_file = argv[++i];
    else if (!std::strcmp(argv[i], "--surface-out") && i + 1 < argc) surface_out = argv[++i];
    else if (!std::strcmp(argv[i], "--mesh-out") && i + 1 < argc) mesh_out = argv[++i];
    else if (!std::strcmp(argv[i], "--fit")) fit = true;
    else if (!std::strcmp(argv[i], "--json")) json = true;
    else return usage(std::string("unknown or incomplete argument '") + argv[i] + "'");
  }
  if (map_file.empty()) return usage("--map is required");
  TsdfMap map;
  std::string err;
  if (!map.load(map_file, &err)) {
    std::cerr << "map_tool: " << err << "\n";
    return 1;
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
  if (fit) {
    FruitShapePipeline pipeline;
    fruits = pipeline.update(surface);
  }
  if (json) {
    std::cout << "{\"blocks\": " << map.blockCount() << ", \"observed_voxels\": " << map.observedVoxelCount()
              << ", \"surface_points\": " << surface.size() << ", \"memory_bytes\": " << map.memoryBytes()
              << ", \"fruits\": [";
    for (std::size_t i = 0; i < fruits.size(); ++i) std::cout << (i ? ", " : "") << fruitJson(fruits[i]);
    std::cout << "]}\n";
  } else if (fit) {
    printFruitTable(std::cout, fruits);
  }
  return 0;
}
