#include <fruit_shape_completion/instrument/sim/image_io.h>
#include <fruit_shape_completion/instrument/sim/scene.h>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>

namespace fruit_shape_completion {
namespace sim {

bool Workspace::contains(const Eigen::Vector3d& p) const {
  if (!p.allFinite()) return false;
  if ((p.array() < box_min.array()).any() || (p.array() > box_max.array()).any()) return false;
  return !has_reach || (p - reach_center).norm() <= reach_radius;
}

std::string RobotMount::describe() const {
  std::ostringstream os;
  if (kind == Kind::kPole)
    os << "UR5e upright on a pole, base at (" << base.transpose() << ")";
  else if (kind == Kind::kGantry)
    os << "UR5e hanging from a gantry, base x in [" << xy_min.x() << ", " << xy_max.x() << "], y in [" << xy_min.y()
       << ", " << xy_max.y() << "], z in [" << top - max_drop << ", " << top << "]";
  else
    os << "no arm (free camera)";
  if (inferred) os << " (inferred: the scene file has no robot entry)";
  return os.str();
}

int Scene::materialIndex(const std::string& name) const {
  for (std::size_t i = 0; i < materials.size(); ++i)
    if (materials[i].name == name) return static_cast<int>(i);
  return -1;
}

namespace {

std::string dirOf(const std::string& path) {
  const auto slash = path.find_last_of('/');
  return slash == std::string::npos ? std::string(".") : path.substr(0, slash);
}

std::string resolve(const std::string& base_dir, const std::string& p) {
  return !p.empty() && p[0] == '/' ? p : base_dir + "/" + p;
}

Eigen::Vector3d vec3(const YAML::Node& n, const std::string& what) {
  if (!n || !n.IsSequence() || n.size() != 3) throw std::runtime_error(what + " must be a list of 3 numbers");
  Eigen::Vector3d v(n[0].as<double>(), n[1].as<double>(), n[2].as<double>());
  if (!v.allFinite()) throw std::runtime_error(what + " is not finite");
  if (v.cwiseAbs().maxCoeff() > kMaxCoordinate) throw std::runtime_error(what + " lies beyond 1e4 m");
  return v;
}

double finiteNumber(const YAML::Node& n, const std::string& what, double limit) {
  const double v = n.as<double>();
  if (!std::isfinite(v) || std::abs(v) > limit)
    throw std::runtime_error(what + " must be a finite number of magnitude at most " + std::to_string(limit));
  return v;
}

// A placed vertex beyond kMaxCoordinate would reach the ray tracer (which aborts on it).
bool placedVertexOk(const Eigen::Vector3f& v, const std::string& path, std::string* error) {
  if (v.allFinite() && v.cwiseAbs().maxCoeff() <= kMaxCoordinate) return true;
  *error = path + ": a vertex lies beyond 1e4 m once placed (mesh units or plant position wrong?)";
  return false;
}

// Reads a mesh's triangles (world frame) with their material indices in `scene`; if asked,
// the vertices' texture coordinates and the texture file each scene material's mesh names.
bool readMesh(const std::string& path, const Eigen::Vector3d& position, double yaw, const Scene& scene,
              bool fruit_only, std::vector<Eigen::Vector3f>* vertices,
              std::vector<Eigen::Vector3i>* triangles, std::vector<int>* triangle_material,
              std::string* error, std::vector<Eigen::Vector2f>* uvs = nullptr,
              std::vector<std::string>* material_texture = nullptr) {
  {
    std::ifstream probe(path);
    if (!probe) {
      *error = path + ": mesh file not found or not readable";
      return false;
    }
  }
  Assimp::Importer importer;
  importer.SetPropertyBool(AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION, true);
  const aiScene* ai = importer.ReadFile(path, aiProcess_Triangulate | aiProcess_PreTransformVertices);
  if (ai == nullptr || !ai->HasMeshes()) {
    *error = path + ": cannot read mesh (" + (ai ? "no meshes" : importer.GetErrorString()) + ")";
    return false;
  }
  const Eigen::Matrix3f R = Eigen::AngleAxisf(static_cast<float>(yaw), Eigen::Vector3f::UnitZ()).toRotationMatrix();
  const Eigen::Vector3f t = position.cast<float>();
  for (unsigned m = 0; m < ai->mNumMeshes; ++m) {
    const aiMesh* mesh = ai->mMeshes[m];
    aiString name;
    ai->mMaterials[mesh->mMaterialIndex]->Get(AI_MATKEY_NAME, name);
    const int mat = scene.materialIndex(name.C_Str());
    if (mat < 0) {
      *error = path + ": unknown material '" + name.C_Str() + "' (not in the scene's materials)";
      return false;
    }
    if (fruit_only && !scene.materials[mat].fruit) continue;
    aiString texture;
    if (material_texture && ai->mMaterials[mesh->mMaterialIndex]->GetTexture(aiTextureType_DIFFUSE, 0, &texture) == AI_SUCCESS &&
        texture.length > 0) {
      material_texture->resize(scene.materials.size());
      (*material_texture)[static_cast<std::size_t>(mat)] = resolve(dirOf(path), texture.C_Str());
    }
    if (uvs)
      for (unsigned v = 0; v < mesh->mNumVertices; ++v)
        uvs->emplace_back(mesh->HasTextureCoords(0) ? Eigen::Vector2f(mesh->mTextureCoords[0][v].x, mesh->mTextureCoords[0][v].y)
                                                    : Eigen::Vector2f::Zero());
    const int base = static_cast<int>(vertices->size());
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const Eigen::Vector3f p(mesh->mVertices[v].x, mesh->mVertices[v].y, mesh->mVertices[v].z);
      if (!p.allFinite()) {
        *error = path + ": non-finite vertex";
        return false;
      }
      vertices->push_back(R * p + t);
      if (!placedVertexOk(vertices->back(), path, error)) return false;
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;  // points and lines left by the triangulation
      triangles->emplace_back(base + face.mIndices[0], base + face.mIndices[1], base + face.mIndices[2]);
      triangle_material->push_back(mat);
    }
  }
  return true;
}

}  // namespace

bool appendMesh(const std::string& path, const Eigen::Vector3d& position, double yaw, int plant,
                Scene* scene, std::string* error) {
  const bool with_uvs = scene->uvs.size() == scene->vertices.size();
  if (!readMesh(path, position, yaw, *scene, false, &scene->vertices, &scene->triangles,
                &scene->triangle_material, error, with_uvs ? &scene->uvs : nullptr))
    return false;
  scene->triangle_plant.resize(scene->triangles.size(), plant);
  return true;
}

bool appendMeshTo(const std::string& path, const Eigen::Vector3d& position, double yaw,
                  const Scene& materials_from, std::vector<Eigen::Vector3f>* vertices,
                  std::vector<Eigen::Vector3i>* triangles, std::vector<int>* triangle_material,
                  std::string* error) {
  return readMesh(path, position, yaw, materials_from, true, vertices, triangles, triangle_material, error);
}

bool loadScene(const std::string& path, Scene* out, std::string* error) {
  Scene scene;
  scene.source = path;
  const std::string dir = dirOf(path);
  std::string where = "";
  try {
    std::ifstream probe(path);
    if (!probe) {
      *error = path + ": scene file not found or not readable";
      return false;
    }
    const YAML::Node root = YAML::LoadFile(path);
    if (!root.IsMap()) throw std::runtime_error("not a YAML mapping");
    scene.name = root["name"] ? root["name"].as<std::string>() : path;
    if (root["frame"]) scene.frame = root["frame"].as<std::string>();
    where = "materials: ";
    const YAML::Node mats = root["materials"];
    if (!mats || !mats.IsMap() || mats.size() == 0) throw std::runtime_error("a 'materials' mapping is required");
    for (const auto& kv : mats) {
      SceneMaterial m;
      m.name = kv.first.as<std::string>();
      const YAML::Node rgb = kv.second["rgb"];
      if (!rgb || !rgb.IsSequence() || rgb.size() != 3)
        throw std::runtime_error(m.name + ".rgb must be a list of 3 values 0-255");
      for (int k = 0; k < 3; ++k) {
        const int c = rgb[k].as<int>();
        if (c < 0 || c > 255) throw std::runtime_error(m.name + ".rgb values must be 0-255");
        m.rgb[k] = static_cast<std::uint8_t>(c);
      }
      m.fruit = kv.second["fruit"] && kv.second["fruit"].as<bool>();
      scene.materials.push_back(m);
    }
    where = "plants: ";
    const YAML::Node plants = root["plants"];
    if (!plants || !plants.IsSequence()) throw std::runtime_error("a 'plants' list is required");
    for (std::size_t i = 0; i < plants.size(); ++i) {
      ScenePlant p;
      if (!plants[i]["mesh"]) throw std::runtime_error("plant " + std::to_string(i) + " has no mesh");
      p.mesh = plants[i]["mesh"].as<std::string>();
      if (plants[i]["fruit_truth"]) p.fruit_truth = plants[i]["fruit_truth"].as<std::string>();
      p.position = vec3(plants[i]["position"], "plant " + std::to_string(i) + " position");
      p.yaw = plants[i]["yaw"] ? finiteNumber(plants[i]["yaw"], "plant " + std::to_string(i) + " yaw", 1e3) : 0.0;
      scene.plants.push_back(p);
    }
    where = "workspace: ";
    if (const YAML::Node ws = root["workspace"]) {
      scene.workspace.box_min = vec3(ws["box_min"], "box_min");
      scene.workspace.box_max = vec3(ws["box_max"], "box_max");
      if (!(scene.workspace.box_min.array() < scene.workspace.box_max.array()).all())
        throw std::runtime_error("box_min must be below box_max on every axis");
      if (ws["reach_center"] || ws["reach_radius"]) {
        scene.workspace.has_reach = true;
        scene.workspace.reach_center = vec3(ws["reach_center"], "reach_center");
        scene.workspace.reach_radius = finiteNumber(ws["reach_radius"], "reach_radius", kMaxCoordinate);
        if (!(scene.workspace.reach_radius > 0)) throw std::runtime_error("reach_radius must be > 0");
      }
    }
    where = "robot: ";
    if (const YAML::Node rb = root["robot"]) {
      const std::string mount = rb["mount"] ? rb["mount"].as<std::string>() : "";
      if (rb["arm"] && rb["arm"].as<std::string>() != "ur5e") throw std::runtime_error("arm must be ur5e");
      if (rb["pole_radius"]) {
        scene.robot.pole_radius = finiteNumber(rb["pole_radius"], "pole_radius", 1.0);
        if (!(scene.robot.pole_radius > 0.0 && scene.robot.pole_radius <= 0.15))
          throw std::runtime_error("pole_radius must be in (0, 0.15] m");
      }
      if (mount == "pole") {
        scene.robot.kind = RobotMount::Kind::kPole;
        scene.robot.base = vec3(rb["base"], "base");
      } else if (mount == "gantry") {
        scene.robot.kind = RobotMount::Kind::kGantry;
        for (const char* key : {"xy_min", "xy_max"}) {
          const YAML::Node n = rb[key];
          if (!n || !n.IsSequence() || n.size() != 2) throw std::runtime_error(std::string(key) + " must be a list of 2 numbers");
          Eigen::Vector2d& v = std::string(key) == "xy_min" ? scene.robot.xy_min : scene.robot.xy_max;
          v = Eigen::Vector2d(finiteNumber(n[0], key, kMaxCoordinate), finiteNumber(n[1], key, kMaxCoordinate));
        }
        if (!(scene.robot.xy_min.array() <= scene.robot.xy_max.array()).all())
          throw std::runtime_error("xy_min must not exceed xy_max");
        scene.robot.top = finiteNumber(rb["top"], "top", kMaxCoordinate);
        scene.robot.max_drop = finiteNumber(rb["max_drop"], "max_drop", 100.0);
        if (scene.robot.max_drop < 0) throw std::runtime_error("max_drop must be >= 0");
      } else if (mount != "none") {
        throw std::runtime_error("mount must be pole, gantry or none");
      }
    } else if (scene.workspace.has_reach) {
      // Files written before the robot entry: an arm's reach sphere means a fixed pole there;
      // otherwise the paper's other set-up, the gantry.
      scene.robot.kind = RobotMount::Kind::kPole;
      scene.robot.base = scene.workspace.reach_center;
      scene.robot.inferred = true;
    } else {
      scene.robot.kind = RobotMount::Kind::kGantry;
      scene.robot.inferred = true;
    }
    where = "camera_start: ";
    if (const YAML::Node cs = root["camera_start"]) {
      scene.camera_start_position = vec3(cs["position"], "position");
      scene.camera_start_look_at = vec3(cs["look_at"], "look_at");
    }
  } catch (const std::exception& e) {
    *error = path + ": malformed scene file: " + where + e.what();
    return false;
  }
  // Plants often share a mesh file: read each file once, then place copies.
  struct Cached {
    std::vector<Eigen::Vector3f> vertices;
    std::vector<Eigen::Vector2f> uvs;
    std::vector<Eigen::Vector3i> triangles;
    std::vector<int> material;
  };
  std::vector<std::string> material_texture;
  std::vector<std::pair<std::string, Cached>> cache;
  for (std::size_t i = 0; i < scene.plants.size(); ++i) {
    const std::string file = resolve(dir, scene.plants[i].mesh);
    const Cached* mesh = nullptr;
    for (const auto& c : cache)
      if (c.first == file) mesh = &c.second;
    if (mesh == nullptr) {
      Cached c;
      if (!readMesh(file, Eigen::Vector3d::Zero(), 0.0, scene, false, &c.vertices, &c.triangles, &c.material, error,
                    &c.uvs, &material_texture))
        return false;
      cache.emplace_back(file, std::move(c));
      mesh = &cache.back().second;
    }
    const Eigen::Matrix3f R =
        Eigen::AngleAxisf(static_cast<float>(scene.plants[i].yaw), Eigen::Vector3f::UnitZ()).toRotationMatrix();
    const Eigen::Vector3f t = scene.plants[i].position.cast<float>();
    const int base = static_cast<int>(scene.vertices.size());
    for (const auto& v : mesh->vertices) {
      scene.vertices.push_back(R * v + t);
      if (!placedVertexOk(scene.vertices.back(), file, error)) return false;
    }
    scene.uvs.insert(scene.uvs.end(), mesh->uvs.begin(), mesh->uvs.end());
    for (std::size_t k = 0; k < mesh->triangles.size(); ++k) {
      scene.triangles.push_back(mesh->triangles[k] + Eigen::Vector3i::Constant(base));
      scene.triangle_material.push_back(mesh->material[k]);
      scene.triangle_plant.push_back(static_cast<int>(i));
    }
  }
  // Textures: a missing one leaves its material in the flat colour (noted); a broken one is an error.
  for (std::size_t m = 0; m < material_texture.size(); ++m) {
    const std::string& file = material_texture[m];
    if (file.empty()) continue;
    std::shared_ptr<const RgbaImage> shared;
    for (const auto& other : scene.materials)
      if (other.texture && other.texture_file == file) shared = other.texture;
    if (!shared) {
      if (!std::ifstream(file).good()) {
        scene.notes.push_back("texture " + file + " of material " + scene.materials[m].name +
                              " not found; drawn in its flat colour");
        continue;
      }
      std::string ext = file.size() >= 4 ? file.substr(file.size() - 4) : "";
      for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
      if (ext != ".tga") {
        scene.notes.push_back("texture " + file + " of material " + scene.materials[m].name +
                              " is not a TGA file (the only format read); drawn in its flat colour");
        continue;
      }
      auto image = std::make_shared<RgbaImage>();
      try {
        if (!readTga(file, image.get(), error)) return false;
      } catch (const std::bad_alloc&) {
        *error = file + ": texture too large for the memory available";
        return false;
      }
      shared = image;
    }
    scene.materials[m].texture = shared;
    scene.materials[m].texture_file = file;
  }
  for (auto& p : scene.plants) {
    p.mesh = resolve(dir, p.mesh);
    if (!p.fruit_truth.empty()) p.fruit_truth = resolve(dir, p.fruit_truth);
  }
  *out = std::move(scene);
  return true;
}

}  // namespace sim
}  // namespace fruit_shape_completion
