#include <fruit_shape_completion/instrument/sim/fruit_mask.h>
#include <fruit_shape_completion/instrument/sim/fruit_truth.h>
#include <fruit_shape_completion/superellipsoid_fit.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <unordered_map>

namespace fruit_shape_completion {
namespace sim {

namespace {

std::uint64_t edgeKey(int a, int b) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) | static_cast<std::uint32_t>(b);
}

// Flips triangles so that every edge shared by two triangles is traversed in opposite
// directions (breadth-first over edge neighbours).
void orientConsistently(std::vector<Eigen::Vector3i>& tris) {
  std::unordered_map<std::uint64_t, std::vector<int>> by_edge;
  for (int t = 0; t < static_cast<int>(tris.size()); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = tris[t][k], b = tris[t][(k + 1) % 3];
      by_edge[edgeKey(std::min(a, b), std::max(a, b))].push_back(t);
    }
  std::vector<char> done(tris.size(), 0);
  std::vector<int> queue;
  for (int seed = 0; seed < static_cast<int>(tris.size()); ++seed) {
    if (done[seed]) continue;
    done[seed] = 1;
    queue.assign(1, seed);
    for (std::size_t h = 0; h < queue.size(); ++h) {
      const Eigen::Vector3i& t = tris[queue[h]];
      for (int k = 0; k < 3; ++k) {
        const int a = t[k], b = t[(k + 1) % 3];
        const auto& nbs = by_edge[edgeKey(std::min(a, b), std::max(a, b))];
        if (nbs.size() != 2) continue;  // boundary or non-manifold: no constraint
        for (int n : nbs) {
          if (done[n]) continue;
          Eigen::Vector3i& u = tris[n];
          bool same = false;  // neighbour runs the shared edge a -> b too: flip it
          for (int j = 0; j < 3; ++j) same = same || (u[j] == a && u[(j + 1) % 3] == b);
          if (same) std::swap(u[1], u[2]);
          done[n] = 1;
          queue.push_back(n);
        }
      }
    }
  }
}

}  // namespace

SolidProperties solidProperties(const std::vector<Eigen::Vector3d>& vertices_in,
                                std::vector<Eigen::Vector3i> tris) {
  SolidProperties out;
  if (tris.empty()) return out;
  std::vector<Eigen::Vector3d> vertices = vertices_in;
  orientConsistently(tris);
  // Close holes: each boundary loop gets a fan around its centroid, oriented like its rim.
  std::unordered_map<std::uint64_t, int> directed;
  for (const auto& t : tris)
    for (int k = 0; k < 3; ++k) ++directed[edgeKey(t[k], t[(k + 1) % 3])];
  std::map<int, int> next;  // boundary edge a -> b, keyed by a
  for (const auto& t : tris)
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      if (!directed.count(edgeKey(b, a))) next.emplace(a, b);
    }
  out.boundary_edges = static_cast<int>(next.size());
  std::set<int> used;
  for (const auto& kv : next) {
    if (used.count(kv.first)) continue;
    std::vector<std::pair<int, int>> loop;
    int a = kv.first;
    while (!used.count(a)) {
      used.insert(a);
      const auto it = next.find(a);
      if (it == next.end()) break;
      loop.emplace_back(a, it->second);
      a = it->second;
    }
    if (loop.size() < 3) continue;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (const auto& e : loop) c += vertices[e.first] / static_cast<double>(loop.size());
    const int ci = static_cast<int>(vertices.size());
    vertices.push_back(c);
    for (const auto& e : loop) tris.emplace_back(e.second, e.first, ci);
  }
  // Divergence theorem: signed tetrahedra against a reference point inside the cloud.
  Eigen::Vector3d ref = Eigen::Vector3d::Zero();
  for (const auto& v : vertices) ref += v / static_cast<double>(vertices.size());
  double vol = 0.0;
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
  for (const auto& t : tris) {
    const Eigen::Vector3d p0 = vertices[t[0]] - ref, p1 = vertices[t[1]] - ref, p2 = vertices[t[2]] - ref;
    const double v = p0.dot(p1.cross(p2)) / 6.0;
    vol += v;
    moment += v * (p0 + p1 + p2) / 4.0;
  }
  if (std::abs(vol) < 1e-15) return out;
  out.centroid = ref + moment / vol;
  out.volume = std::abs(vol);
  return out;
}

std::vector<FruitTruth> computeFruitTruth(const Scene& materials_from,
                                          const std::vector<Eigen::Vector3f>& vertices,
                                          const std::vector<Eigen::Vector3i>& triangles,
                                          const std::vector<int>& triangle_material,
                                          const std::vector<int>& triangle_plant,
                                          std::vector<int>* triangle_fruit) {
  if (triangle_fruit) triangle_fruit->assign(triangles.size(), -1);
  // Weld vertices by position (10 um grid).
  std::vector<int> weld(vertices.size());
  std::vector<Eigen::Vector3d> welded;
  std::map<std::array<std::int64_t, 3>, int> index;
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const std::array<std::int64_t, 3> key = {std::llround(vertices[i].x() * 1e5), std::llround(vertices[i].y() * 1e5),
                                             std::llround(vertices[i].z() * 1e5)};
    const auto ins = index.emplace(key, static_cast<int>(welded.size()));
    if (ins.second) welded.push_back(vertices[i].cast<double>());
    weld[i] = ins.first->second;
  }
  // Fruit triangles, without degenerate ones and without duplicates (back faces).
  std::vector<int> fruit_tris;
  std::set<std::array<int, 3>> seen;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const int m = triangle_material[t];
    if (m < 0 || !materials_from.materials[m].fruit) continue;
    std::array<int, 3> w = {weld[triangles[t][0]], weld[triangles[t][1]], weld[triangles[t][2]]};
    if (w[0] == w[1] || w[1] == w[2] || w[0] == w[2]) continue;
    std::array<int, 3> sorted = w;
    std::sort(sorted.begin(), sorted.end());
    if (!seen.insert(sorted).second) continue;
    fruit_tris.push_back(static_cast<int>(t));
  }
  // Connected components (union-find over welded vertices).
  std::vector<int> parent(welded.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&parent](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (int t : fruit_tris)
    for (int k = 1; k < 3; ++k) parent[find(weld[triangles[t][k]])] = find(weld[triangles[t][0]]);
  std::map<int, std::vector<int>> components;  // root -> triangles, in order of first triangle
  std::vector<int> order;
  for (int t : fruit_tris) {
    const int r = find(weld[triangles[t][0]]);
    if (!components.count(r)) order.push_back(r);
    components[r].push_back(t);
  }

  // Stable ids whatever the triangle order of the files: by plant, then top to bottom.
  std::vector<std::pair<std::array<double, 4>, int>> keyed;
  for (int root : order) {
    const auto& comp = components[root];
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int t : comp) mean += welded[weld[triangles[t][0]]] / static_cast<double>(comp.size());
    const double plant = triangle_plant.empty() ? 0.0 : triangle_plant[comp.front()];
    keyed.push_back({{plant, -std::round(mean.z() * 1e4), std::round(mean.x() * 1e4), std::round(mean.y() * 1e4)}, root});
  }
  std::sort(keyed.begin(), keyed.end());
  order.clear();
  for (const auto& k : keyed) order.push_back(k.second);

  std::vector<FruitTruth> fruits;
  for (int root : order) {
    const std::vector<int>& comp = components[root];
    std::vector<Eigen::Vector3i> tris;
    for (int t : comp) tris.emplace_back(weld[triangles[t][0]], weld[triangles[t][1]], weld[triangles[t][2]]);
    const SolidProperties solid = solidProperties(welded, tris);
    if (solid.volume < 1e-6) continue;  // below 1 cm^3: a fragment, not a fruit
    FruitTruth f;
    f.id = static_cast<int>(fruits.size());
    f.plant = triangle_plant.empty() ? -1 : triangle_plant[comp.front()];
    f.center = solid.centroid;
    f.volume = solid.volume;
    f.box_min = f.box_max = welded[tris.front()[0]];
    for (const auto& t : tris)
      for (int k = 0; k < 3; ++k) {
        f.box_min = f.box_min.cwiseMin(welded[t[k]]);
        f.box_max = f.box_max.cwiseMax(welded[t[k]]);
      }
    f.triangles = static_cast<int>(comp.size());
    f.boundary_edges = solid.boundary_edges;
    std::map<int, int> votes;
    for (int t : comp) ++votes[triangle_material[t]];
    const int mat = std::max_element(votes.begin(), votes.end(), [](const auto& a, const auto& b) {
                      return a.second < b.second;
                    })->first;
    f.color = colorClass(materials_from.materials[mat].rgb);
    // The paper's ground truth: a superellipsoid fitted to area-uniform surface samples.
    std::vector<double> area(comp.size());
    for (std::size_t i = 0; i < comp.size(); ++i) {
      const Eigen::Vector3d a = welded[tris[i][0]], b = welded[tris[i][1]], c = welded[tris[i][2]];
      area[i] = 0.5 * (b - a).cross(c - a).norm();
    }
    std::mt19937 rng(1234 + f.id);
    std::discrete_distribution<int> pick(area.begin(), area.end());
    std::uniform_real_distribution<double> u(0, 1);
    PointList samples;
    for (int s = 0; s < 3000; ++s) {
      const Eigen::Vector3i& t = tris[pick(rng)];
      double r1 = u(rng), r2 = u(rng);
      if (r1 + r2 > 1) {
        r1 = 1 - r1;
        r2 = 1 - r2;
      }
      samples.push_back(welded[t[0]] + r1 * (welded[t[1]] - welded[t[0]]) + r2 * (welded[t[2]] - welded[t[0]]));
    }
    FitParams fp;
    fp.alpha = fp.gamma = 0.0;
    fp.max_rms = 1.0;  // always report it
    fp.noise_bias = 0.0;  // samples of the mesh itself: its residual is the lobes, not noise
    fp.size_prior = 0.0;  // ... seen all round: nothing to choose between
    const FitResult fit = fitSuperellipsoid(samples, f.center, fp);
    f.se = fit.shape;
    f.se_volume = fit.shape.volume();
    if (triangle_fruit)
      for (int t : comp) (*triangle_fruit)[t] = f.id;
    fruits.push_back(f);
  }
  // Back faces share their front face's fruit id.
  if (triangle_fruit) {
    std::map<std::array<int, 3>, int> id_of;
    for (std::size_t t = 0; t < triangles.size(); ++t)
      if ((*triangle_fruit)[t] >= 0) {
        std::array<int, 3> w = {weld[triangles[t][0]], weld[triangles[t][1]], weld[triangles[t][2]]};
        std::sort(w.begin(), w.end());
        id_of[w] = (*triangle_fruit)[t];
      }
    for (std::size_t t = 0; t < triangles.size(); ++t) {
      const int m = triangle_material[t];
      if ((*triangle_fruit)[t] >= 0 || m < 0 || !materials_from.materials[m].fruit) continue;
      std::array<int, 3> w = {weld[triangles[t][0]], weld[triangles[t][1]], weld[triangles[t][2]]};
      std::sort(w.begin(), w.end());
      const auto it = id_of.find(w);
      if (it != id_of.end()) (*triangle_fruit)[t] = it->second;
    }
  }
  return fruits;
}

std::vector<FruitTruth> computeFruitTruth(const Scene& scene, std::vector<int>* triangle_fruit) {
  return computeFruitTruth(scene, scene.vertices, scene.triangles, scene.triangle_material,
                           scene.triangle_plant, triangle_fruit);
}

}  // namespace sim
}  // namespace fruit_shape_completion
