#pragma once
// A sparse TSDF (truncated signed distance) map: voxels grouped in cubic blocks created on
// demand, so memory follows what was seen (the voxblox layout; defaults as the paper: 4 mm
// voxels, 64 voxels per block side).
//
// Not synchronised: const methods may run concurrently, except markUpdates() (it writes the
// update log that forEachBlockUpdatedSince reads); updates need exclusive access (the
// superellipsoid estimator guards its map with one mutex for all of these).
#include <fruit_shape_completion/grid_cell.h>
#include <fruit_shape_completion/types.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <unordered_set>
#include <vector>

namespace fruit_shape_completion {

struct TsdfVoxel {
  float distance = 0.0f;  // signed distance to the surface [m], positive in front
  float weight = 0.0f;    // 0: never observed
};

struct TsdfMapParams {
  double voxel_size = 0.004;  // [m]
  // Per block. The paper's voxblox map has 64 (25.6 cm blocks, 2 MiB each, mostly empty around
  // a fruit); 16 (6.4 cm, 32 KiB) holds a mapped fruit in about 0.3 MiB instead of 3, with the
  // same voxels and the same fits (docs/benchmarks.md, "A greenhouse row").
  int voxels_per_side = 16;
  // The largest block side a map may have: a saved map's file is read back only up to it (a block
  // of 128^3 voxels reserves 16 MiB), so a map built with a larger side could not be loaded again.
  static constexpr int kMaxVoxelsPerSide = 128;
  // Memory the map's blocks may reserve [MiB]; a block is 32 KiB at 16 voxels a side. At the
  // budget no block is created: the blocks held keep updating, the parts of views that need new
  // ones are dropped, counted and reported (IntegrationReport::over_budget).
  double memory_budget_mb = 2048.0;
  std::size_t blockBytes() const;  // reserved by one block
  std::size_t maxBlocks() const;   // the blocks the budget holds
  // Optional crop box (map frame): nothing outside it is stored.
  bool use_crop_box = false;
  Eigen::Vector3d crop_min = Eigen::Vector3d::Constant(-1e9);
  Eigen::Vector3d crop_max = Eigen::Vector3d::Constant(1e9);
  // Throws std::invalid_argument naming the first bad value.
  void validate() const;
};

// Integer voxel coordinates in the map (voxel i spans [i, i+1) * voxel_size).
using VoxelIndex = GridCell;

struct TsdfBlock {
  TsdfBlock(const VoxelIndex& origin, int voxels_per_side);  // throws std::bad_alloc
  VoxelIndex origin;  // global index of the block's first voxel
  int side;
  // side^3, x fastest. From calloc, not a zero-filled vector: the OS maps zeroed pages on first
  // touch, so a new block costs only the pages its fruit reaches, not 2 MiB of writes.
  struct FreeDeleter {
    void operator()(TsdfVoxel* p) const { std::free(p); }
  };
  std::unique_ptr<TsdfVoxel[], FreeDeleter> voxels;
  std::size_t voxelCount() const { return static_cast<std::size_t>(side) * side * side; }
  // One bit per voxel, set once it has weight > 0: readers walk only the observed voxels.
  std::vector<std::uint64_t> observed_bits;
  // The map's change count when the block was last handed out for an update: a reader that
  // remembers it knows whether the block may have changed since.
  std::uint64_t revision = 0;
  std::uint64_t logged_in = 0;  // the update log's generation it was last logged in (TsdfMap)

  std::uint32_t indexOf(int x, int y, int z) const { return static_cast<std::uint32_t>(x + side * (y + side * z)); }
  Eigen::Vector3i coordsOf(std::uint32_t idx) const {
    return Eigen::Vector3i(idx % side, (idx / side) % side, idx / (side * side));
  }
  // fn(index) for each observed voxel, ascending.
  template <typename Fn>
  void forEachObserved(Fn&& fn) const {
    for (std::size_t w = 0; w < observed_bits.size(); ++w)
      for (std::uint64_t b = observed_bits[w]; b != 0; b &= b - 1)
        fn(static_cast<std::uint32_t>(w * 64 + static_cast<unsigned>(__builtin_ctzll(b))));
  }
  std::size_t observedCount() const;
  void markObserved(std::uint32_t idx) { observed_bits[idx >> 6] |= std::uint64_t(1) << (idx & 63); }

  // Folds one measurement (weight > 0) into voxel `idx`.
  void update(std::uint32_t idx, double sdf, double weight, double max_weight) {
    TsdfVoxel& v = voxels[idx];
    markObserved(idx);
    const double wsum = v.weight + weight;
    v.distance = static_cast<float>((v.distance * v.weight + sdf * weight) / wsum);
    v.weight = static_cast<float>(wsum < max_weight ? wsum : max_weight);
  }
};

class TsdfMap {
 public:
  explicit TsdfMap(const TsdfMapParams& params = TsdfMapParams());

  const TsdfMapParams& params() const { return params_; }
  double voxelSize() const { return params_.voxel_size; }
  int voxelsPerSide() const { return params_.voxels_per_side; }

  VoxelIndex voxelIndexOf(const Eigen::Vector3d& p) const { return cellOf(p, 1.0 / params_.voxel_size); }
  Eigen::Vector3d voxelCenter(const VoxelIndex& v) const {
    return (v.cast<double>().array() + 0.5) * params_.voxel_size;
  }
  bool insideCropBox(const Eigen::Vector3d& p) const;

  // The voxel at a global index, or nullptr if its block does not exist.
  const TsdfVoxel* voxel(const VoxelIndex& v) const;
  // The global index of the first voxel of the block holding voxel v.
  VoxelIndex blockOriginOf(const VoxelIndex& v) const;
  // The block with that origin, created if needed; nullptr if the memory budget, the key range or the
  // crop box (the block lies wholly outside it) forbid it.
  TsdfBlock* blockForUpdate(const VoxelIndex& block_origin);
  // Whether the key range and the crop box allow a block at that origin (what blockForUpdate
  // checks besides the budget): a missing block that may be there was refused by the budget.
  bool blockAllowed(const VoxelIndex& block_origin) const;
  // Sets a voxel (used by load); false if its block cannot be created.
  bool setVoxel(const VoxelIndex& v, const TsdfVoxel& value);

  std::size_t blockCount() const { return blocks_.size(); }
  bool atBudget() const { return blocks_.size() >= max_blocks_; }
  std::size_t blockVoxels() const {
    const std::size_t n = params_.voxels_per_side;
    return n * n * n;
  }
  std::size_t observedVoxelCount() const;
  std::size_t memoryBytes() const;
  // Empty, with the parameters it was constructed with (a loaded file's block side goes).
  void clear();

  // Differs between maps and changes when the map is cleared or loaded: block revisions are
  // comparable only within one epoch.
  std::uint64_t epoch() const { return epoch_; }

  template <typename Fn>  // fn(const TsdfBlock&), in the order of their keys
  void forEachBlock(Fn&& fn) const {
    for (const auto& kb : blocks_) fn(*kb.second);
  }

  // The update log: a reader that visits only the blocks updated since it last looked, not
  // every block of a map that holds a whole row. markUpdates() starts a new generation and
  // returns it; forEachBlockUpdatedSince(mark, fn) calls fn(const TsdfBlock&) once for each
  // block updated since markUpdates() returned `mark`, or returns false (fn not called) when the
  // log no longer reaches back that far (the map was cleared or loaded, or the log was trimmed):
  // then the reader visits every block. Any number of readers may keep their own marks.
  std::uint64_t markUpdates() const;
  template <typename Fn>
  bool forEachBlockUpdatedSince(std::uint64_t mark, Fn&& fn) const {
    if (mark < log_start_ || mark > log_generation_) return false;
    auto it = firstLoggedIn(mark);
    // A block is logged once per generation: only a mark older than the last needs the set.
    const bool one_generation = it == update_log_.end() || it->generation == update_log_.back().generation;
    std::unordered_set<const TsdfBlock*> seen;
    for (; it != update_log_.end(); ++it)
      if (one_generation || seen.insert(it->block).second) fn(*it->block);
    return true;
  }

  // Binary file: the observed voxels only, written atomically (atomic_file.h). load() leaves
  // the map unchanged on error.
  bool save(const std::string& path, std::string* error) const;
  // The file's bytes (for a caller that copies under a lock and writes outside it).
  void serialize(std::string* bytes) const;
  // `rest`, if given, receives the file's bytes after the map (at most kMaxRestBytes + 1): where a
  // host keeps its own records beside the map, which readers of the map alone skip.
  bool load(const std::string& path, std::string* error, std::string* rest = nullptr);
  static constexpr std::size_t kMaxRestBytes = std::size_t(16) << 20;

 private:
  std::uint64_t blockKeyOf(const VoxelIndex& block_origin) const;
  bool blockInRange(const VoxelIndex& block_origin) const;

  TsdfMapParams params_;
  TsdfMapParams configured_;  // as constructed; load() may take a file's, clear() goes back
  std::size_t max_blocks_;
  std::map<std::uint64_t, std::unique_ptr<TsdfBlock>> blocks_;
  // Rays touch the same block many times in a row: the last block updated is kept.
  VoxelIndex cached_origin_ = VoxelIndex::Zero();
  TsdfBlock* cached_block_ = nullptr;
  std::uint64_t epoch_;
  std::uint64_t revision_ = 0;
  struct LogEntry {
    std::uint64_t generation;
    const TsdfBlock* block;
  };
  // Blocks in the order they were first updated in each generation (ascending generations).
  // Mutable: readers mark generations under the same lock that guards their reading.
  mutable std::vector<LogEntry> update_log_;
  mutable std::uint64_t log_generation_ = 1, log_start_ = 1;
  void logUpdate(TsdfBlock* block) {
    if (block->logged_in == log_generation_) return;
    block->logged_in = log_generation_;
    update_log_.push_back({log_generation_, block});
  }
  // The first entry of `generation` or later.
  std::vector<LogEntry>::iterator firstLoggedIn(std::uint64_t generation) const {
    return std::lower_bound(update_log_.begin(), update_log_.end(), generation,
                            [](const LogEntry& e, std::uint64_t g) { return e.generation < g; });
  }
  void resetLog() const {
    update_log_.clear();
    log_start_ = ++log_generation_;
  }
};

}  // namespace fruit_shape_completion
