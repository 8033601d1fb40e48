#include <fruit_shape_completion/tsdf_surface.h>

#include <fruit_shape_completion/atomic_file.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

namespace fruit_shape_completion {

namespace {

// Neighbour access that stays inside the block's array when it can (no hash lookup).
struct BlockView {
  const TsdfMap& map;
  const TsdfBlock& block;
  int n;
  const TsdfVoxel* at(int lx, int ly, int lz) const {
    if (lx >= 0 && ly >= 0 && lz >= 0 && lx < n && ly < n && lz < n)
      return &block.voxels[block.indexOf(lx, ly, lz)];
    return map.voxel(block.origin + VoxelIndex(lx, ly, lz));
  }
};

bool usable(const TsdfVoxel* v, double min_weight) { return v != nullptr && v->weight >= min_weight; }

// The surface points of one block, appended to `out`.
void appendBlockSurface(const TsdfMap& map, const TsdfBlock& block, const SurfaceExtractionParams& params,
                        PointList* out) {
  const double vs = map.voxelSize();
  const float max_d = static_cast<float>(params.max_distance_voxels * vs);
  const BlockView view{map, block, map.voxelsPerSide()};
  block.forEachObserved([&](std::uint32_t idx) {
    const TsdfVoxel& v = block.voxels[idx];
    if (v.weight < params.min_weight || std::abs(v.distance) >= max_d) return;
    const Eigen::Vector3i l = block.coordsOf(idx);
    const int lx = l.x(), ly = l.y(), lz = l.z();
    Eigen::Vector3d c = map.voxelCenter(block.origin + VoxelIndex(lx, ly, lz));
    if (params.project_to_zero_crossing) {
      Eigen::Vector3d g;
      bool ok = true;
      for (int k = 0; k < 3 && ok; ++k) {
        const int dx = k == 0, dy = k == 1, dz = k == 2;
        const TsdfVoxel* plus = view.at(lx + dx, ly + dy, lz + dz);
        const TsdfVoxel* minus = view.at(lx - dx, ly - dy, lz - dz);
        const bool p = usable(plus, params.min_weight), m = usable(minus, params.min_weight);
        if (p && m) g[k] = (plus->distance - minus->distance) / (2.0 * vs);
        else if (p) g[k] = (plus->distance - v.distance) / vs;
        else if (m) g[k] = (v.distance - minus->distance) / vs;
        else ok = false;
      }
      const double gn = g.norm();
      // A distance field has |gradient| ~ 1; far from that the neighbourhood is unreliable.
      if (ok && gn > 0.5 && gn < 2.0) c -= (v.distance / gn) * (g / gn);
    }
    out->push_back(c);
  });
}

GridCell blockCoordsOf(const TsdfMap& map, const TsdfBlock& block) { return block.origin / map.voxelsPerSide(); }

}  // namespace

PointList extractSurfacePoints(const TsdfMap& map, const SurfaceExtractionParams& params) {
  PointList out;
  map.forEachBlock([&](const TsdfBlock& block) { appendBlockSurface(map, block, params, &out); });
  return out;
}

bool IncrementalSurfaceExtractor::reextract(const TsdfMap& map, const TsdfBlock& block, CachedBlock* entry) {
  PointList points;
  appendBlockSurface(map, block, params_, &points);
  ++last_extracted_;
  if (points == entry->points.get()) return false;
  last_blocks_.changed.push_back(blockCoordsOf(map, block));
  entry->points = std::move(points);
  return true;
}

const SurfaceBlocks& IncrementalSurfaceExtractor::extractBlocks(const TsdfMap& map) {
  const bool fresh = map.epoch() != epoch_ || blocks_.empty();
  if (map.epoch() != epoch_) {
    blocks_.clear();
    epoch_ = map.epoch();
  }
  // Without projection only the blocks the map logged as updated since the last call are
  // visited (a row's map holds thousands); the list of blocks with points is kept in key order.
  if (!fresh && marked_ && !params_.project_to_zero_crossing) {
    SurfaceBlocks& out = last_blocks_;
    out.changed.clear();
    out.all_changed = false;
    last_extracted_ = 0;
    auto visit = [&](const TsdfBlock& block) {
      const GridCell b = blockCoordsOf(map, block);
      const std::uint64_t key = packCellKey(b);
      const auto [it, inserted] = blocks_.try_emplace(key);
      CachedBlock& entry = it->second;
      const bool stale = inserted || entry.revision != block.revision;
      entry.revision = block.revision;
      if (!stale || !reextract(map, block, &entry)) return;
      const auto pos = std::lower_bound(out.blocks.begin(), out.blocks.end(), key,
                                        [](const SurfaceBlocks::Block& x, std::uint64_t k) { return packCellKey(x.block) < k; });
      const bool listed = pos != out.blocks.end() && packCellKey(pos->block) == key;
      if (entry.points.empty()) {
        if (listed) out.blocks.erase(pos);
      } else if (listed) {
        pos->points = entry.points;
      } else {
        out.blocks.insert(pos, {b, entry.points});
      }
    };
    if (map.forEachBlockUpdatedSince(mark_, visit)) {
      mark_ = map.markUpdates();
      return out;
    }
  }
  // With projection, a surface point also reads the voxels next to it, so a changed block's
  // neighbours are extracted again too; without, a block's own revision tells (below).
  std::unordered_map<std::uint64_t, char> changed;
  if (params_.project_to_zero_crossing) {
    map.forEachBlock([&](const TsdfBlock& block) {
      const GridCell b = blockCoordsOf(map, block);
      const auto it = blocks_.find(packCellKey(b));
      if (it != blocks_.end() && it->second.revision == block.revision) return;
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) changed[packCellKey(b + GridCell(dx, dy, dz))] = 1;
    });
  }
  // The cache is updated in place: a view changes a few blocks of a map that only grows (blocks
  // go only when the map is cleared or loaded, which changes its epoch).
  last_extracted_ = 0;
  SurfaceBlocks& out = last_blocks_;
  const std::size_t before = out.blocks.size();
  out.blocks.clear();
  out.blocks.reserve(before + before / 8 + 16);
  out.changed.clear();
  out.block_size = map.voxelsPerSide() * map.voxelSize();
  out.all_changed = fresh;
  out.points_in_blocks = !params_.project_to_zero_crossing;
  std::size_t present = 0;
  map.forEachBlock([&](const TsdfBlock& block) {
    const GridCell b = blockCoordsOf(map, block);
    const std::uint64_t key = packCellKey(b);
    const auto [it, inserted] = blocks_.try_emplace(key);
    CachedBlock& entry = it->second;
    ++present;
    const bool stale = params_.project_to_zero_crossing ? changed.count(key) > 0 : entry.revision != block.revision;
    entry.revision = block.revision;
    if (inserted || stale) reextract(map, block, &entry);
    if (!entry.points.empty()) out.blocks.push_back({b, entry.points});
  });
  if (blocks_.size() != present) {  // blocks went without a new epoch: their points went too
    std::unordered_map<std::uint64_t, char> in_map;
    map.forEachBlock([&](const TsdfBlock& block) { in_map[packCellKey(blockCoordsOf(map, block))] = 1; });
    for (auto it = blocks_.begin(); it != blocks_.end();) {
      if (in_map.count(it->first)) {
        ++it;
        continue;
      }
      if (!it->second.points.empty()) out.changed.push_back(cellOf(it->second.points.front(), 1.0 / out.block_size));
      it = blocks_.erase(it);
    }
  }
  mark_ = map.markUpdates();
  marked_ = true;
  return out;
}

TriangleMesh extractSurfaceMesh(const TsdfMap& map, double min_weight) {
  TriangleMesh mesh;
  const int n = map.voxelsPerSide();
  const double vs = map.voxelSize();
  const float skip = static_cast<float>(std::sqrt(3.0) * vs);
  // Six tetrahedra around the cube diagonal 0-7; corner bit 1: +x, 2: +y, 4: +z.
  static const int kTets[6][4] = {{0, 7, 1, 3}, {0, 7, 3, 2}, {0, 7, 2, 6},
                                  {0, 7, 6, 4}, {0, 7, 4, 5}, {0, 7, 5, 1}};
  map.forEachBlock([&](const TsdfBlock& block) {
    const BlockView view{map, block, n};
    block.forEachObserved([&](std::uint32_t idx) {
      const TsdfVoxel& v0 = block.voxels[idx];
      if (v0.weight < min_weight || std::abs(v0.distance) > skip) return;
      const Eigen::Vector3i l = block.coordsOf(idx);
      const int lx = l.x(), ly = l.y(), lz = l.z();
      double d[8];
      Eigen::Vector3d p[8];
      bool ok = true, pos = false, neg = false;
      for (int c = 0; c < 8 && ok; ++c) {
        const int cx = c & 1, cy = (c >> 1) & 1, cz = (c >> 2) & 1;
        const TsdfVoxel* v = view.at(lx + cx, ly + cy, lz + cz);
        if (!usable(v, min_weight)) {
          ok = false;
          break;
        }
        d[c] = v->distance;
        (d[c] < 0 ? neg : pos) = true;
        p[c] = map.voxelCenter(block.origin + VoxelIndex(lx + cx, ly + cy, lz + cz));
      }
      if (!ok || !pos || !neg) return;
      for (const auto& tet : kTets) {
        int inside[4], outside[4], ni = 0, no = 0;
        for (int k : tet) (d[k] < 0 ? inside[ni++] : outside[no++]) = k;
        if (ni == 0 || no == 0) continue;
        auto cross = [&](int a, int b) {
          const double t = d[a] / (d[a] - d[b]);
          return Eigen::Vector3d(p[a] + t * (p[b] - p[a]));
        };
        Eigen::Vector3d in_c = Eigen::Vector3d::Zero(), out_c = Eigen::Vector3d::Zero();
        for (int i = 0; i < ni; ++i) in_c += p[inside[i]] / ni;
        for (int i = 0; i < no; ++i) out_c += p[outside[i]] / no;
        const Eigen::Vector3d outward = out_c - in_c;
        auto emit = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
          const int base = static_cast<int>(mesh.vertices.size());
          const bool flip = (b - a).cross(c - a).dot(outward) < 0;
          mesh.vertices.push_back(a.cast<float>());
          mesh.vertices.push_back((flip ? c : b).cast<float>());
          mesh.vertices.push_back((flip ? b : c).cast<float>());
          mesh.triangles.emplace_back(base, base + 1, base + 2);
        };
        if (ni == 1 || no == 1) {
          const int lone = ni == 1 ? inside[0] : outside[0];
          const int* others = ni == 1 ? outside : inside;
          emit(cross(lone, others[0]), cross(lone, others[1]), cross(lone, others[2]));
        } else {  // 2 and 2: a quad
          const Eigen::Vector3d q0 = cross(inside[0], outside[0]), q1 = cross(inside[0], outside[1]),
                                q2 = cross(inside[1], outside[1]), q3 = cross(inside[1], outside[0]);
          emit(q0, q1, q2);
          emit(q0, q2, q3);
        }
      }
    });
  });
  return mesh;
}

bool TriangleMesh::writePly(const std::string& path, std::string* error) const {
  // Written whole and renamed into place: a kill or a full disk leaves the previous file.
  std::ostringstream out;
  out << std::setprecision(9);  // a float's digits: a map far from its frame's origin keeps its millimetres
  out << "ply\nformat ascii 1.0\nelement vertex " << vertices.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nelement face " << triangles.size()
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const auto& v : vertices) out << v.x() << ' ' << v.y() << ' ' << v.z() << '\n';
  for (const auto& t : triangles) out << "3 " << t.x() << ' ' << t.y() << ' ' << t.z() << '\n';
  return writeFileAtomically(path, out.str(), error);
}

}  // namespace fruit_shape_completion
