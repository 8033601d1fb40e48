#pragma once
// Ground-truth fruits of a scene: the connected components of its fruit-material triangles
// (vertices welded by position, duplicate back faces dropped, orientation made consistent),
// each with its enclosed volume (stem hole closed by fans), centroid and colour class, plus the
// paper's kind of ground truth: a superellipsoid fitted to the fruit's mesh surface.
#include <fruit_shape_completion/instrument/sim/scene.h>
#include <fruit_shape_completion/superellipsoid.h>

#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace sim {

struct FruitTruth {
  int id = -1;
  int plant = -1;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  // centroid of the enclosed solid
  double volume = 0.0;                               // enclosed volume [m^3]
  Eigen::Vector3d box_min = Eigen::Vector3d::Zero(), box_max = Eigen::Vector3d::Zero();  // mesh AABB
  Superellipsoid se;                                 // fitted to the mesh surface
  double se_volume = 0.0;
  std::string color;         // "red", "yellow", "other"
  int triangles = 0;         // fruit triangles after dropping duplicates
  int boundary_edges = 0;    // open edges closed before taking the volume
};

// `triangle_fruit` (optional) gets one entry per scene triangle: the fruit id, or -1.
std::vector<FruitTruth> computeFruitTruth(const Scene& scene, std::vector<int>* triangle_fruit = nullptr);

// The same for a bare triangle soup with per-triangle materials of `scene` (e.g. a fruit-only
// mesh loaded with appendMeshTo).
std::vector<FruitTruth> computeFruitTruth(const Scene& materials_from,
                                          const std::vector<Eigen::Vector3f>& vertices,
                                          const std::vector<Eigen::Vector3i>& triangles,
                                          const std::vector<int>& triangle_material,
                                          const std::vector<int>& triangle_plant,
                                          std::vector<int>* triangle_fruit);

// Enclosed volume and centroid of a closed or nearly closed triangle set (holes are closed by a
// fan around each boundary loop's centroid; orientation is made consistent first).
struct SolidProperties {
  double volume = 0.0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  int boundary_edges = 0;
};
SolidProperties solidProperties(const std::vector<Eigen::Vector3d>& vertices,
                                std::vector<Eigen::Vector3i> triangles);

}  // namespace sim
}  // namespace fruit_shape_completion
