// Clusters formed again only around the blocks a view changed (FruitShapePipeline::update with
// SurfaceBlocks). A cluster is a connected component: one that reaches a changed block is
// formed from the changed blocks grown until no such cluster has a point outside them; every
// cluster that reaches none is the same as before, and so is its fruit.
#include <fruit_shape_completion/fruit_shape_pipeline.h>

#include <algorithm>
#include <limits>
#include <unordered_map>
#include <unordered_set>

namespace fruit_shape_completion {

std::vector<std::vector<int>> FruitShapePipeline::localClusters(const SurfaceBlocks& blocks, PointList* sub,
                                                                std::vector<Track>* untouched) {
  const double inv = 1.0 / blocks.block_size;
  std::unordered_map<std::uint64_t, GridCell> grown;  // the blocks formed again, by key
  auto grow = [&](const GridCell& c) { return grown.emplace(packCellKey(c), c).second; };
  for (const GridCell& c : pending_changed_) grow(c);
  // The blocks and their neighbours: a point within the cluster tolerance (less than a block)
  // of a grown block's point lies in one of them.
  auto nearGrown = [&]() {
    std::unordered_set<std::uint64_t> near;
    near.reserve(27 * grown.size());
    for (const auto& [key, c] : grown)
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) near.insert(packCellKey(c + GridCell(dx, dy, dz)));
    return near;
  };
  // Fruits with points in the grown blocks are formed again, with every part of their cluster
  // (a split), and all their blocks grow the region: the rest of such a fruit may now be a
  // cluster of its own.
  std::vector<char> touched(tracks_.size(), 0);
  auto touchTracks = [&]() {
    bool more = false;
    for (std::size_t k = 0; k < tracks_.size(); ++k) {
      if (touched[k]) continue;
      for (const GridCell& b : tracks_[k].blocks)
        if (grown.count(packCellKey(b))) {
          touched[k] = 1;
          break;
        }
      if (!touched[k]) continue;
      for (std::size_t j = 0; j < tracks_.size(); ++j)
        if (!touched[j] && tracks_[j].cluster_signature == tracks_[k].cluster_signature &&
            tracks_[j].cluster_points == tracks_[k].cluster_points)
          touched[j] = 1;
      more = true;
    }
    if (!more) return false;
    bool grew = false;
    for (std::size_t k = 0; k < tracks_.size(); ++k)
      if (touched[k])
        for (const GridCell& b : tracks_[k].blocks) grew = grow(b) || grew;
    return grew;
  };

  ClusteringParams every = params_.clustering;  // all components: a truncated one may be small
  every.min_size = 1;
  every.max_size = std::numeric_limits<int>::max();
  std::vector<std::vector<int>> found, components;
  std::vector<std::size_t> gathered, gathered_before;  // the blocks (indices) whose points are in sub
  int skipped = 0;  // non-finite points of the last gathering
  // A component no fruit tracks (one too large or too small to fit: fruits and leaves grown into
  // one, say) grows the region by one ring of blocks per pass, each pass clustering all that was
  // gathered: a long one would cost passes times points on every view. After a few passes the
  // region takes at once every block with points connected to it through blocks with points
  // (a component cannot leave them: the tolerance is below a block), and the next pass is the last.
  constexpr int kPassesBeforeConnected = 4;
  auto growConnected = [&]() {
    std::unordered_map<std::uint64_t, GridCell> occupied;
    for (const auto& b : blocks.blocks) occupied.emplace(packCellKey(b.block), b.block);
    std::vector<GridCell> frontier;
    for (const auto& kv : grown) frontier.push_back(kv.second);
    while (!frontier.empty()) {
      const GridCell c = frontier.back();
      frontier.pop_back();
      for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const auto it = occupied.find(packCellKey(c + GridCell(dx, dy, dz)));
            if (it != occupied.end() && grow(it->second)) frontier.push_back(it->second);
          }
    }
  };
  bool connected = false;  // once: it only speeds the growth up, the passes after it still finish it
  for (;;) {
    if (!connected && stats_.cluster_passes == kPassesBeforeConnected) {
      growConnected();
      connected = true;
    }
    if (touchTracks()) continue;
    const std::unordered_set<std::uint64_t> near = nearGrown();
    gathered.clear();
    for (std::size_t i = 0; i < blocks.blocks.size(); ++i)
      if (near.count(packCellKey(blocks.blocks[i].block))) gathered.push_back(i);
    // Grown blocks that bring no new points (the ring already held them) leave the components
    // as they were: only which points lie in grown blocks changes.
    const bool same_points = !gathered_before.empty() && gathered == gathered_before;
    std::vector<char> in_grown;  // per point of sub
    if (!same_points) sub->clear();
    skipped = 0;
    for (const std::size_t i : gathered) {
      const SurfaceBlocks::Block& b = blocks.blocks[i];
      const char g = grown.count(packCellKey(b.block)) ? 1 : 0;
      for (const Point& p : b.points) {
        if (!p.allFinite()) {
          ++skipped;
          continue;
        }
        if (!same_points) sub->push_back(p);
        in_grown.push_back(g);
      }
    }
    if (!same_points) {
      components = euclideanClusters(*sub, every);
      ++stats_.cluster_passes;
    }
    gathered_before.swap(gathered);
    found.clear();
    bool grew = false;
    for (const auto& component : components) {
      bool reaches = false;
      for (int j : component) reaches = reaches || in_grown[static_cast<std::size_t>(j)];
      if (!reaches) continue;  // a cluster of the ring only: not changed (or cut off here)
      for (int j : component)
        if (!in_grown[static_cast<std::size_t>(j)]) grew = grow(cellOf((*sub)[static_cast<std::size_t>(j)], inv)) || grew;
      found.push_back(component);
    }
    if (!grew) break;
  }
  stats_.non_finite_points += skipped;
  std::vector<std::vector<int>> clusters;
  for (auto& c : found)
    if (stats_.left_out.admits(static_cast<int>(c.size()), params_.clustering)) clusters.push_back(std::move(c));
  std::stable_sort(clusters.begin(), clusters.end(), [](const auto& l, const auto& r) { return l.size() > r.size(); });
  std::vector<Track> kept;
  for (std::size_t k = 0; k < tracks_.size(); ++k)
    (touched[k] ? kept : *untouched).push_back(std::move(tracks_[k]));
  tracks_.swap(kept);
  return clusters;
}

}  // namespace fruit_shape_completion
