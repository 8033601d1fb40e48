#include <fruit_shape_completion/instrument/sim/procedural_scene.h>
#include <fruit_shape_completion/instrument/sim/synthetic_fruit.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <filesystem>

namespace fruit_shape_completion {
namespace sim {

namespace {

enum Material { kRed = 0, kRedDark, kYellow, kLeaf, kLeafLight, kStem };

// The mean colours of the capsicum model's textures (their opaque texels).
std::vector<SceneMaterial> proceduralMaterials() {
  auto material = [](const char* name, std::array<std::uint8_t, 3> rgb, bool fruit) {
    SceneMaterial m;
    m.name = name;
    m.rgb = rgb;
    m.fruit = fruit;
    return m;
  };
  return {material("fruit_red", {{227, 88, 23}}, true),   material("fruit_red_dark", {{204, 41, 9}}, true),
          material("fruit_yellow", {{162, 154, 35}}, true), material("leaf", {{60, 83, 22}}, false),
          material("leaf_light", {{60, 79, 18}}, false),    material("stem", {{101, 118, 40}}, false)};
}

// A plant's geometry in its own frame (origin at the stem base, z up).
struct PlantMesh {
  std::vector<Eigen::Vector3f> vertices;
  std::vector<Eigen::Vector3i> triangles;
  std::vector<int> material;

  int vertex(const Eigen::Vector3d& p) {
    vertices.push_back(p.cast<float>());
    return static_cast<int>(vertices.size()) - 1;
  }
  void tri(int a, int b, int c, int m) {
    triangles.emplace_back(a, b, c);
    material.push_back(m);
  }

  // A closed cylinder from p0 to p1.
  void cylinder(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double r, int m, int seg = 8) {
    const Eigen::Vector3d axis = (p1 - p0).normalized();
    const Eigen::Vector3d x = axis.unitOrthogonal(), y = axis.cross(x);
    const int c0 = vertex(p0), c1 = vertex(p1);
    std::vector<int> a(seg), b(seg);
    for (int i = 0; i < seg; ++i) {
      const double t = 2 * M_PI * i / seg;
      const Eigen::Vector3d off = r * (std::cos(t) * x + std::sin(t) * y);
      a[i] = vertex(p0 + off);
      b[i] = vertex(p1 + off);
    }
    for (int i = 0; i < seg; ++i) {
      const int j = (i + 1) % seg;
      tri(a[i], a[j], b[j], m);
      tri(a[i], b[j], b[i], m);
      tri(c0, a[j], a[i], m);
      tri(c1, b[i], b[j], m);
    }
  }

  // A closed star-shaped solid from a radius function on a latitude/longitude grid.
  void starSolid(const SyntheticFruit& f, int m, int n_theta = 22, int n_phi = 32) {
    const int top = vertex(f.surfacePoint(Eigen::Vector3d::UnitZ()));
    std::vector<int> ring_prev;
    for (int i = 1; i < n_theta; ++i) {
      const double th = M_PI * i / n_theta;
      std::vector<int> ring(n_phi);
      for (int j = 0; j < n_phi; ++j) {
        const double ph = 2 * M_PI * j / n_phi;
        ring[j] = vertex(f.surfacePoint(Eigen::Vector3d(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th))));
      }
      for (int j = 0; j < n_phi; ++j) {
        const int k = (j + 1) % n_phi;
        if (ring_prev.empty()) {
          tri(top, ring[j], ring[k], m);
        } else {
          tri(ring_prev[j], ring[j], ring[k], m);
          tri(ring_prev[j], ring[k], ring_prev[k], m);
        }
      }
      ring_prev = ring;
    }
    const int bottom = vertex(f.surfacePoint(-Eigen::Vector3d::UnitZ()));
    for (int j = 0; j < n_phi; ++j) tri(ring_prev[(j + 1) % n_phi], ring_prev[j], bottom, m);
  }

  // A leaf blade: a curved, pointed ellipse on a small grid, from `base` along `dir`.
  void leaf(const Eigen::Vector3d& base, const Eigen::Vector3d& dir, const Eigen::Vector3d& side,
            double length, double width, double droop, int m) {
    const int nl = 6, nw = 4;
    std::vector<std::vector<int>> id(nl + 1, std::vector<int>(nw + 1));
    const Eigen::Vector3d down = dir.cross(side).normalized();
    for (int i = 0; i <= nl; ++i) {
      const double s = static_cast<double>(i) / nl;
      const double half = 0.5 * width * std::sin(M_PI * std::pow(s, 0.8));  // pointed at both ends
      for (int j = 0; j <= nw; ++j) {
        const double w = (2.0 * j / nw - 1.0) * half;
        const Eigen::Vector3d p = base + s * length * dir + w * side +
                                  (droop * s * s * length + 0.15 * std::abs(w)) * down;
        id[i][j] = vertex(p);
      }
    }
    for (int i = 0; i < nl; ++i)
      for (int j = 0; j < nw; ++j) {
        tri(id[i][j], id[i + 1][j], id[i + 1][j + 1], m);
        tri(id[i][j], id[i + 1][j + 1], id[i][j + 1], m);
      }
  }
};

PlantMesh makePlant(std::mt19937& rng, const ProceduralSceneParams& p) {
  std::uniform_real_distribution<double> u(0, 1);
  PlantMesh mesh;
  const double height = 0.7 + 0.2 * u(rng);
  mesh.cylinder(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, height), 0.008, kStem);

  struct Ball {
    Eigen::Vector3d c;
    double r;
  };
  std::vector<Ball> fruits;
  const int n_fruits = p.min_fruits + static_cast<int>(u(rng) * (p.max_fruits - p.min_fruits + 1));
  for (int tries = 0; static_cast<int>(fruits.size()) < n_fruits && tries < 200; ++tries) {
    // Pepper shape of a random volume in [min_volume, max_volume].
    const double target = p.min_volume + u(rng) * (p.max_volume - p.min_volume);
    const double r0 = 0.04, h0 = r0 * (0.8 + 0.5 * u(rng));
    // Draws in named steps: the order in which a call's arguments are evaluated is up to the
    // compiler, and a seeded scene must be the same from any compiler.
    const double heading = 2 * M_PI * u(rng), lean = 0.5 * (u(rng) - 0.5);
    const Eigen::Matrix3d tilt =
        (Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(lean, Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
    const int lobes = 3 + static_cast<int>(2 * u(rng));
    const double lobe_depth = 0.06 + 0.06 * u(rng), taper = 0.15 + 0.25 * u(rng);
    SyntheticFruit unit = SyntheticFruit::pepper(r0, h0, lobes, lobe_depth, taper, Eigen::Vector3d::Zero(), tilt);
    const double scale = std::cbrt(target / unit.volume(20000));
    const double reach = scale * std::max(r0, h0) * 1.15;
    const double az = 2 * M_PI * u(rng);
    const double z = 0.2 + (height - 0.3) * u(rng);
    const double off = reach + 0.012 + 0.03 * u(rng);
    const Eigen::Vector3d c(off * std::cos(az), off * std::sin(az), z);
    bool free = true;
    for (const auto& f : fruits) free = free && (f.c - c).norm() > f.r + reach + 0.015;
    if (!free) continue;
    SyntheticFruit fruit = unit;
    fruit.center = c;
    const auto base_radius = unit.radius;
    fruit.radius = [base_radius, scale](const Eigen::Vector3d& d) { return scale * base_radius(d); };
    const int mat = u(rng) < p.yellow_fraction ? kYellow : (u(rng) < 0.5 ? kRed : kRedDark);
    mesh.starSolid(fruit, mat);
    // Stem cap and a peduncle to the main stem.
    const Eigen::Vector3d top = fruit.surfacePoint(Eigen::Vector3d::UnitZ());
    const Eigen::Vector3d up = tilt.col(2);
    mesh.cylinder(top - 0.006 * up, top + 0.012 * up, 0.006, kStem, 6);
    mesh.cylinder(top + 0.012 * up, Eigen::Vector3d(0, 0, top.z() + 0.03), 0.003, kStem, 5);
    fruits.push_back({c, reach});
  }

  for (int i = 0, tries = 0; i < p.leaves && tries < 20 * p.leaves; ++tries) {
    const double z = 0.08 + (height - 0.05) * u(rng);
    const double az = 2 * M_PI * u(rng);
    const Eigen::Vector3d out(std::cos(az), std::sin(az), 0.0);
    const double rise = 0.6 * (u(rng) - 0.3);
    const Eigen::Vector3d dir = (out + Eigen::Vector3d(0, 0, rise)).normalized();
    // Blades roll about their midrib, so many face the camera rather than show their edge.
    const Eigen::Vector3d side = Eigen::AngleAxisd(1.2 * (u(rng) - 0.5), dir) * Eigen::Vector3d::UnitZ().cross(out).normalized();
    const double length = 0.10 + 0.08 * u(rng), width = 0.05 + 0.045 * u(rng);
    const Eigen::Vector3d base = Eigen::Vector3d(0, 0, z) + (0.015 + 0.06 * u(rng)) * out;
    // Leaves must not cut through fruits: test points along the blade.
    bool free = true;
    for (double s = 0.0; s <= 1.0 && free; s += 0.1)
      for (const auto& f : fruits) free = free && (base + s * length * dir - f.c).norm() > f.r + 0.006 + 0.5 * width * std::sin(M_PI * s);
    if (!free) continue;
    const double curl = 0.3 * u(rng);
    mesh.leaf(base, dir, side, length, width, curl, u(rng) < 0.5 ? kLeaf : kLeafLight);
    ++i;
  }
  return mesh;
}

}  // namespace

Scene generateProceduralScene(const ProceduralSceneParams& p) {
  std::mt19937 rng(p.seed);
  Scene scene;
  scene.name = "procedural_" + std::to_string(p.seed);
  scene.source = "procedural:" + std::to_string(p.seed);
  scene.materials = proceduralMaterials();
  const double row_length = (p.plants_per_row - 1) * p.plant_spacing;
  for (int r = 0; r < p.rows; ++r)
    for (int i = 0; i < p.plants_per_row; ++i) {
      const PlantMesh mesh = makePlant(rng, p);
      ScenePlant plant;
      plant.mesh = "plant_" + std::to_string(scene.plants.size()) + ".obj";
      plant.position = Eigen::Vector3d(i * p.plant_spacing - 0.5 * row_length, 0.6 + r * p.row_spacing, 0.0);
      plant.yaw = 2 * M_PI * std::uniform_real_distribution<double>(0, 1)(rng);
      const Eigen::Matrix3f R = Eigen::AngleAxisf(static_cast<float>(plant.yaw), Eigen::Vector3f::UnitZ()).toRotationMatrix();
      const int base = static_cast<int>(scene.vertices.size());
      for (const auto& v : mesh.vertices) scene.vertices.push_back(R * v + plant.position.cast<float>());
      for (std::size_t k = 0; k < mesh.triangles.size(); ++k) {
        scene.triangles.push_back(mesh.triangles[k] + Eigen::Vector3i::Constant(base));
        scene.triangle_material.push_back(mesh.material[k]);
        scene.triangle_plant.push_back(static_cast<int>(scene.plants.size()));
      }
      scene.plants.push_back(plant);
    }
  // The camera works from the aisles: in front of the first row, between rows, behind the last.
  scene.workspace.box_min = Eigen::Vector3d(-0.5 * row_length - 0.5, 0.0, 0.15);
  scene.workspace.box_max = Eigen::Vector3d(0.5 * row_length + 0.5, 0.6 + (p.rows - 1) * p.row_spacing + 0.6, 1.3);
  // A gantry over the rows, as in the paper's scenarios 2 and 3.
  scene.robot.kind = RobotMount::Kind::kGantry;
  scene.robot.xy_min = scene.workspace.box_min.head<2>();
  scene.robot.xy_max = scene.workspace.box_max.head<2>();
  scene.camera_start_position = Eigen::Vector3d(0.0, 0.15, 0.8);
  scene.camera_start_look_at = Eigen::Vector3d(0.0, 0.6, 0.45);
  return scene;
}

bool loadSceneSpec(const std::string& spec, Scene* scene, std::string* error) {
  auto number = [&](const std::string& text, const char* what, unsigned long* out) {
    char* end = nullptr;
    *out = std::strtoul(text.c_str(), &end, 10);
    if (text.empty() || *end != '\0') {
      *error = "scene '" + spec + "': " + what + " must be a whole number";
      return false;
    }
    return true;
  };
  if (spec.rfind("procedural-row", 0) == 0) {
    // procedural-row[:SEED[:PLANTS]]: one long row, as a trolley or gantry scans it.
    ProceduralSceneParams p;
    p.plants_per_row = 80;
    std::string rest = spec.substr(14);
    if (!rest.empty()) {
      if (rest[0] != ':') {
        *error = "scene '" + spec + "': expected 'procedural-row', 'procedural-row:SEED' or 'procedural-row:SEED:PLANTS'";
        return false;
      }
      rest = rest.substr(1);
      const std::size_t colon = rest.find(':');
      unsigned long v = 0;
      if (!number(rest.substr(0, colon), "the seed", &v)) return false;
      p.seed = static_cast<unsigned>(v);
      if (colon != std::string::npos) {
        if (!number(rest.substr(colon + 1), "the number of plants", &v)) return false;
        if (v < 1 || v > 2000) {
          *error = "scene '" + spec + "': the number of plants must be 1..2000";
          return false;
        }
        p.plants_per_row = static_cast<int>(v);
      }
    }
    *scene = generateProceduralScene(p);
    scene->name = "procedural_row_" + std::to_string(p.seed) + "_" + std::to_string(p.plants_per_row);
    scene->source = spec;
    // The robot starts at the row's first plant.
    const double start_x = scene->plants.front().position.x();
    scene->camera_start_position.x() = start_x;
    scene->camera_start_look_at.x() = start_x;
    return true;
  }
  if (spec.rfind("procedural", 0) == 0) {
    ProceduralSceneParams p;
    if (spec.size() > 10) {
      unsigned long v = 0;
      if (spec[10] != ':' || spec.size() == 11) {
        *error = "scene '" + spec + "': expected 'procedural' or 'procedural:SEED'";
        return false;
      }
      if (!number(spec.substr(11), "the seed", &v)) return false;
      p.seed = static_cast<unsigned>(v);
    }
    *scene = generateProceduralScene(p);
    return true;
  }
  return loadScene(spec, scene, error);
}

bool writeSceneFiles(const Scene& scene, const std::string& dir, std::string* error) {
  std::error_code mkdir_error;
  std::filesystem::create_directories(dir, mkdir_error);
  auto fail = [&](const std::string& what) {
    *error = dir + ": " + what;
    return false;
  };
  {
    std::ofstream mtl(dir + "/scene.mtl");
    if (!mtl) return fail("cannot write scene.mtl");
    for (const auto& m : scene.materials)
      mtl << "newmtl " << m.name << "\nKd " << m.rgb[0] / 255.0 << ' ' << m.rgb[1] / 255.0 << ' '
          << m.rgb[2] / 255.0 << "\n\n";
  }
  for (std::size_t pi = 0; pi < scene.plants.size(); ++pi) {
    const ScenePlant& plant = scene.plants[pi];
    const Eigen::Matrix3f Rt = Eigen::AngleAxisf(static_cast<float>(plant.yaw), Eigen::Vector3f::UnitZ()).toRotationMatrix().transpose();
    std::ofstream obj(dir + "/plant_" + std::to_string(pi) + ".obj");
    if (!obj) return fail("cannot write plant_" + std::to_string(pi) + ".obj");
    obj << "# fruit_shape_completion procedural plant (plant frame, metres)\nmtllib scene.mtl\n";
    std::vector<int> local(scene.vertices.size(), -1);
    int n = 0;
    for (std::size_t t = 0; t < scene.triangles.size(); ++t) {
      if (scene.triangle_plant[t] != static_cast<int>(pi)) continue;
      for (int k = 0; k < 3; ++k) {
        const int v = scene.triangles[t][k];
        if (local[v] >= 0) continue;
        local[v] = ++n;
        const Eigen::Vector3f p = Rt * (scene.vertices[v] - plant.position.cast<float>());
        obj << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
      }
    }
    int current = -1;
    for (std::size_t t = 0; t < scene.triangles.size(); ++t) {
      if (scene.triangle_plant[t] != static_cast<int>(pi)) continue;
      if (scene.triangle_material[t] != current) {
        current = scene.triangle_material[t];
        obj << "usemtl " << scene.materials[current].name << '\n';
      }
      obj << "f " << local[scene.triangles[t][0]] << ' ' << local[scene.triangles[t][1]] << ' '
          << local[scene.triangles[t][2]] << '\n';
    }
    if (!obj) return fail("write error");
  }
  std::ofstream yaml(dir + "/scene.yaml");
  if (!yaml) return fail("cannot write scene.yaml");
  yaml.precision(9);
  auto v3 = [](const Eigen::Vector3d& v) {
    std::ostringstream os;
    os.precision(9);
    os << '[' << v.x() << ", " << v.y() << ", " << v.z() << ']';
    return os.str();
  };
  yaml << "# Written by fruit_shape_completion from " << scene.source << "\nname: " << scene.name
       << "\nframe: " << scene.frame << "\nplants:\n";
  for (std::size_t pi = 0; pi < scene.plants.size(); ++pi)
    yaml << "  - {mesh: plant_" << pi << ".obj, position: " << v3(scene.plants[pi].position)
         << ", yaw: " << scene.plants[pi].yaw << "}\n";
  yaml << "materials:\n";
  for (const auto& m : scene.materials)
    yaml << "  " << m.name << ": {rgb: [" << int(m.rgb[0]) << ", " << int(m.rgb[1]) << ", " << int(m.rgb[2])
         << "]" << (m.fruit ? ", fruit: true" : "") << "}\n";
  yaml << "workspace:\n  box_min: " << v3(scene.workspace.box_min) << "\n  box_max: " << v3(scene.workspace.box_max) << '\n';
  if (scene.workspace.has_reach)
    yaml << "  reach_center: " << v3(scene.workspace.reach_center) << "\n  reach_radius: " << scene.workspace.reach_radius << '\n';
  const RobotMount& rb = scene.robot;
  auto v2 = [](const Eigen::Vector2d& v) { return "[" + std::to_string(v.x()) + ", " + std::to_string(v.y()) + "]"; };
  if (rb.kind == RobotMount::Kind::kPole)
    yaml << "robot: {arm: ur5e, mount: pole, base: " << v3(rb.base) << ", pole_radius: " << rb.pole_radius << "}\n";
  else if (rb.kind == RobotMount::Kind::kGantry)
    yaml << "robot: {arm: ur5e, mount: gantry, xy_min: " << v2(rb.xy_min) << ", xy_max: " << v2(rb.xy_max)
         << ", top: " << rb.top << ", max_drop: " << rb.max_drop << ", pole_radius: " << rb.pole_radius << "}\n";
  else
    yaml << "robot: {mount: none}\n";
  yaml << "camera_start: {position: " << v3(scene.camera_start_position) << ", look_at: " << v3(scene.camera_start_look_at) << "}\n";
  if (!yaml) return fail("write error");
  return true;
}

}  // namespace sim
}  // namespace fruit_shape_completion
