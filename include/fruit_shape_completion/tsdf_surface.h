#pragma once
// The fruit surface of a TsdfMap: a point cloud for the fitter, a triangle mesh for display.
#include <fruit_shape_completion/tsdf_map.h>

#include <string>
#include <vector>

namespace fruit_shape_completion {

struct SurfaceExtractionParams {
  double max_distance_voxels = 0.75;  // |distance| below this many voxels: on the surface (voxblox's default)
  double min_weight = 1e-3;           // and observed with at least this weight
  // Move each surface voxel centre along the distance gradient onto the zero crossing. It
  // cuts the RMS surface error about threefold (4 cm sphere: 1.1 -> 0.35 mm) but not the
  // error of fitted volumes (the centres scatter evenly about the surface), and doubles the
  // extraction time; off: voxel centres, as voxblox emits them.
  bool project_to_zero_crossing = false;
};

PointList extractSurfacePoints(const TsdfMap& map, const SurfaceExtractionParams& params = {});

struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<Eigen::Vector3i> triangles;  // indices into vertices, counter-clockwise seen from outside
  bool writePly(const std::string& path, std::string* error) const;
};

// Marching tetrahedra over the cubes of observed voxel centres (six tetrahedra per cube, no
// 256-case table), triangles oriented toward positive distance (outside).
TriangleMesh extractSurfaceMesh(const TsdfMap& map, double min_weight = 1e-3);

}  // namespace fruit_shape_completion
