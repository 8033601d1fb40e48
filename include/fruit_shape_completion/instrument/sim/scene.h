#pragma once
// A simulated glasshouse scene: plant meshes placed in the world, a colour per material, which
// materials are fruit, and where the camera may go. Loaded from the scene files of
// ../shared/data/scenes (YAML + COLLADA/OBJ meshes, read with Assimp) or generated
// (procedural_scene.h). All geometry is flattened into one world-frame triangle soup.
#include <fruit_shape_completion/types.h>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace fruit_shape_completion {
namespace sim {

struct RgbaImage;

struct SceneMaterial {
  std::string name;
  std::array<std::uint8_t, 3> rgb{{128, 128, 128}};  // flat colour (the ideal simulation's)
  bool fruit = false;
  // The mesh's diffuse texture, if it names one that could be read; its alpha channel (if any)
  // cuts the surface, as Gazebo draws leaves.
  std::shared_ptr<const RgbaImage> texture;
  std::string texture_file;
};

struct Workspace {
  Eigen::Vector3d box_min = Eigen::Vector3d::Constant(-1.0);
  Eigen::Vector3d box_max = Eigen::Vector3d::Constant(1.0);
  bool has_reach = false;  // an arm: the camera also stays within reach_radius of reach_center
  Eigen::Vector3d reach_center = Eigen::Vector3d::Zero();
  double reach_radius = 0.0;
  bool contains(const Eigen::Vector3d& p) const;
};

// Where the camera's arm stands (the paper's simulation): a UR5e upright on a fixed pole, or
// hanging upside down from a pole on a ceiling gantry that moves its base to
// (x, y, top - drop), x and y within xy_min..xy_max, drop within 0..max_drop.
struct RobotMount {
  enum class Kind { kNone, kPole, kGantry };
  Kind kind = Kind::kNone;  // kNone: a free-flying camera (the ideal simulation)
  Eigen::Vector3d base = Eigen::Vector3d(0, 0, 0.86);  // kPole: the arm's base
  Eigen::Vector2d xy_min = Eigen::Vector2d(-1, -1), xy_max = Eigen::Vector2d(1, 1);  // kGantry
  double top = 1.69, max_drop = 0.5;                                                  // kGantry [m]
  double pole_radius = 0.05;
  bool inferred = false;  // the scene file had no `robot:` entry; loadScene chose this one
  std::string describe() const;
};

struct ScenePlant {
  std::string mesh;         // path as given in the scene file (resolved against its folder)
  std::string fruit_truth;  // optional fruit-only mesh of the same plant
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double yaw = 0.0;
};

struct Scene {
  std::string name;
  std::string frame = "world";
  std::string source;  // file it came from, or "procedural:SEED"
  std::vector<ScenePlant> plants;
  std::vector<SceneMaterial> materials;
  std::vector<Eigen::Vector3f> vertices;        // world frame [m]
  std::vector<Eigen::Vector2f> uvs;             // per vertex texture coordinates, or empty
  std::vector<Eigen::Vector3i> triangles;
  std::vector<int> triangle_material;           // index into materials
  std::vector<int> triangle_plant;              // index into plants
  Workspace workspace;
  RobotMount robot;
  Eigen::Vector3d camera_start_position = Eigen::Vector3d(0, 0, 1);
  Eigen::Vector3d camera_start_look_at = Eigen::Vector3d(0, 1, 1);
  std::vector<std::string> notes;  // what loadScene chose or left out (e.g. a missing texture)

  int materialIndex(const std::string& name) const;  // -1 if unknown
};

// Loads a scene file. On failure returns false and sets *error to a message naming the file
// and the problem (missing mesh, unknown material, malformed YAML, bad values).
bool loadScene(const std::string& path, Scene* scene, std::string* error);

// Appends a mesh file's triangles to the scene, placed by `position` and `yaw`; every material
// of the mesh must be in scene->materials. Used by loadScene and by the tests.
bool appendMesh(const std::string& path, const Eigen::Vector3d& position, double yaw, int plant,
                Scene* scene, std::string* error);

// Reads only the triangles of fruit materials of a mesh file (e.g. a fruit-only ground-truth
// mesh), placed like a plant. Material names must be in `scene`.
bool appendMeshTo(const std::string& path, const Eigen::Vector3d& position, double yaw,
                  const Scene& materials_from, std::vector<Eigen::Vector3f>* vertices,
                  std::vector<Eigen::Vector3i>* triangles, std::vector<int>* triangle_material,
                  std::string* error);

}  // namespace sim
}  // namespace fruit_shape_completion
