#pragma once
// A surface cloud as the map's blocks hold it: each block's points, shared with the extractor's
// cache (no copy of the whole surface per update), and which blocks changed since the previous
// cloud. With it the pipeline re-clusters only around what a view changed
// (FruitShapePipeline::update), so per-view work does not grow with the map.
#include <fruit_shape_completion/grid_cell.h>
#include <fruit_shape_completion/shared_points.h>

#include <cstddef>
#include <vector>

namespace fruit_shape_completion {

struct SurfaceBlocks {
  double block_size = 0.0;  // [m] edge of a block; points lie in the block floor(p / block_size)
  struct Block {
    GridCell block;
    SharedPoints points;
  };
  std::vector<Block> blocks;      // every block with points, in the map's order
  std::vector<GridCell> changed;  // blocks whose points changed, appeared or went since the previous cloud
  bool all_changed = false;       // no previous cloud to compare with (first, cleared or loaded map)
  // Whether a block's points stay inside it (not projected onto the zero crossing, which may
  // move a point to the next block): only then may the pipeline re-cluster locally.
  bool points_in_blocks = true;

  std::size_t size() const {
    std::size_t n = 0;
    for (const auto& b : blocks) n += b.points.size();
    return n;
  }
  // All points, block after block.
  PointList cloud() const {
    PointList out;
    out.reserve(size());
    for (const auto& b : blocks) out.insert(out.end(), b.points.begin(), b.points.end());
    return out;
  }
};

}  // namespace fruit_shape_completion
