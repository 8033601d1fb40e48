#pragma once
// A surface cloud as the map's blocks hold it: which points came from which block, and which
// blocks changed since the previous cloud. With it the pipeline re-clusters only around what a
// view changed (FruitShapePipeline::update), so per-view work does not grow with the map.
#include <fruit_shape_completion/grid_cell.h>

#include <cstddef>
#include <vector>

namespace fruit_shape_completion {

struct SurfaceBlocks {
  double block_size = 0.0;  // [m] edge of a block; points lie in the block floor(p / block_size)
  struct Range {
    GridCell block;
    std::size_t begin = 0, end = 0;  // the cloud's points [begin, end) came from this block
  };
  std::vector<Range> ranges;      // every block with points, in the cloud's order
  std::vector<GridCell> changed;  // blocks whose points changed, appeared or went since the previous cloud
  bool all_changed = false;       // no previous cloud to compare with (first, cleared or loaded map)
};

}  // namespace fruit_shape_completion
