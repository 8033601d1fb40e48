#pragma once
// A sparse TSDF (truncated signed distance) map: voxels grouped in cubic blocks kept in a hash
// map and created on demand, so memory follows what was seen (the voxblox layout; defaults
// as the paper: 4 mm voxels, 64 voxels per block side).
//
// Not synchronised: const methods may run concurrently, updates need exclusive access (the
// superellipsoid estimator guards its map with a mutex).
#include <fruit_shape_completion/types.h>

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

namespace fruit_shape_completion {

struct TsdfVoxel {
  float distance = 0.0f;  // signed distance to the surface [m], positive in front
  float weight = 0.0f;    // 0: never observed
};

struct TsdfMapParams {
  double voxel_size = 0.004;  // [m]
  int voxels_per_side = 64;   // per block
  // Blocks are never created beyond this many; points that would need more are dropped and
  // counted. 1024 blocks of 64^3 voxels are 2 GiB.
  int max_blocks = 1024;
  // Back each block of 2 MiB or more with a transparent huge page where the OS offers them
  // (Linux, THP "madvise" or "always"): a fresh full frame then takes ~100 page faults instead
  // of ~10 thousand, but zeroes whole blocks (190 MB): measured once 71 -> 66 ms, later no gain
  // (README). Every block is then resident whole (as memoryBytes() counts it anyway) and the
  // kernel may stall to compact memory for a huge page (once seen: 0.5 s).
  bool huge_pages = false;
  // Optional crop box (map frame): nothing outside it is stored.
  bool use_crop_box = false;
  Eigen::Vector3d crop_min = Eigen::Vector3d::Constant(-1e9);
  Eigen::Vector3d crop_max = Eigen::Vector3d::Constant(1e9);
  // Throws std::invalid_argument naming the first bad value.
  void validate() const;
};

// Integer voxel coordinates in the map (voxel i spans [i, i+1) * voxel_size).
using VoxelIndex = Eigen::Matrix<std::int64_t, 3, 1>;

// Where voxel (x, y, z) of a block lives in the block's array. For power-of-two sides it is
// Morton (Z-) order: each 2x2x2 group of voxels fills one 64-byte cache line and each 8x8x8
// group one 4 KiB page, so a ray's band stays on a few lines and pages in any direction (with
// x fastest, each step along y or z is another line, and along z another page). Measured on
// the full-frame benchmark (a wall facing the camera) it is within noise of x fastest (warm
// 36 vs 36-38 ms, fresh 80 vs 83 ms of ray casting). Other sides use x fastest.
class VoxelLayout {
 public:
  explicit VoxelLayout(int voxels_per_side);
  std::uint32_t index(int x, int y, int z) const { return x_[x] + y_[y] + z_[z]; }
  Eigen::Vector3i coords(std::uint32_t idx) const;
  // The tables index() adds up, for inner loops that keep their own pointers.
  const std::uint32_t* xTable() const { return x_.data(); }
  const std::uint32_t* yTable() const { return y_.data(); }
  const std::uint32_t* zTable() const { return z_.data(); }
  bool morton() const { return morton_; }

 private:
  int n_;
  bool morton_;
  std::vector<std::uint32_t> x_, y_, z_;
};

// Frees a block's voxel array (mmap'd for blocks of 2 MiB or more on Linux, else calloc'd:
// allocateVoxels()).
struct VoxelArrayDeleter {
  std::size_t mapped_bytes = 0;  // 0: calloc'd
  void operator()(TsdfVoxel* p) const;
};

struct TsdfBlock {
  TsdfBlock(const VoxelIndex& origin, int voxels_per_side, bool huge_page);
  VoxelIndex origin;  // global index of the block's first voxel
  std::uint32_t voxel_count;  // voxels_per_side^3
  // voxels_per_side^3 in VoxelLayout order, zeroed by the OS on first touch, so the untouched
  // part of a block costs no time. With huge_page (a 64^3 block of 8-byte voxels is exactly
  // one 2 MiB page) the first touch faults the whole block in at once instead of page by page.
  std::unique_ptr<TsdfVoxel[], VoxelArrayDeleter> voxels;
  // One bit per voxel (layout index), set once it has weight > 0. A bit per update costs less
  // than a list: no branch on the voxel's old weight, nothing to grow or sort when a view sees
  // new space, and readers walk the observed voxels in memory order. 32 KiB for 64^3 voxels.
  std::vector<std::uint64_t> observed_bits;
  // fn(layout index) for each observed voxel, ascending.
  template <typename Fn>
  void forEachObserved(Fn&& fn) const {
    for (std::size_t w = 0; w < observed_bits.size(); ++w)
      for (std::uint64_t b = observed_bits[w]; b != 0; b &= b - 1)
        fn(static_cast<std::uint32_t>(w * 64 + static_cast<unsigned>(__builtin_ctzll(b))));
  }
  std::size_t observedCount() const;
  void markObserved(std::uint32_t idx) { observed_bits[idx >> 6] |= std::uint64_t(1) << (idx & 63); }

  // Call before the first access to voxel idx in a batch of updates. The first access to a
  // fresh page decides its cost: a read maps the shared zero page and the write after it
  // faults again; this makes it a plain store (one fault), once per 4 KiB of voxels.
  void touchForWrite(std::uint32_t idx) {
    const std::uint32_t group = idx / kVoxelsPerPage;
    std::uint64_t& word = written_groups[group >> 6];
    const std::uint64_t bit = std::uint64_t(1) << (group & 63);
    if ((word & bit) == 0) {
      word |= bit;
      voxels[idx] = TsdfVoxel();  // never written before: already zero, the store only maps it
    }
  }
  static constexpr std::uint32_t kVoxelsPerPage = 4096 / sizeof(TsdfVoxel);
  // One bit per kVoxelsPerPage voxels: set once any of them may have been written.
  std::vector<std::uint64_t> written_groups;

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
  const VoxelLayout& layout() const { return layout_; }

  VoxelIndex voxelIndexOf(const Eigen::Vector3d& p) const;
  Eigen::Vector3d voxelCenter(const VoxelIndex& v) const {
    return (v.cast<double>().array() + 0.5) * params_.voxel_size;
  }
  bool insideCropBox(const Eigen::Vector3d& p) const;

  // The voxel at a global index, or nullptr if its block does not exist.
  const TsdfVoxel* voxel(const VoxelIndex& v) const;
  // The global index of the first voxel of the block holding voxel v.
  VoxelIndex blockOriginOf(const VoxelIndex& v) const {
    if (block_shift_ >= 0) {  // floor to a multiple of a power of two: clear the low bits
      const std::int64_t mask = ~((std::int64_t(1) << block_shift_) - 1);
      return VoxelIndex(v.x() & mask, v.y() & mask, v.z() & mask);
    }
    return blockOriginByDivision(v);
  }
  // The block with that origin, created if needed; nullptr if max_blocks or the crop box
  // (the block lies wholly outside it) forbid it.
  TsdfBlock* blockForUpdate(const VoxelIndex& block_origin) {
    // Rays touch the same block many times in a row: the last answer is kept (inline, so a
    // hit costs a compare, not a call).
    if (cached_block_ != nullptr && block_origin == cached_origin_) return cached_block_;
    return findOrCreateBlock(block_origin);
  }
  // Sets a voxel (used by load); false if its block cannot be created.
  bool setVoxel(const VoxelIndex& v, const TsdfVoxel& value);

  std::size_t blockCount() const { return blocks_.size(); }
  std::size_t blockVoxels() const {
    const std::size_t n = params_.voxels_per_side;
    return n * n * n;
  }
  std::size_t observedVoxelCount() const;
  std::size_t memoryBytes() const;
  void clear();

  // In the order of their keys, whatever the order they were made in (so maps built by one
  // thread or several iterate alike).
  template <typename Fn>  // fn(const TsdfBlock&)
  void forEachBlock(Fn&& fn) const {
    for (const auto& kb : ordered_) fn(*kb.second);
  }

  // Binary file: the observed voxels only. load() leaves the map unchanged on error.
  bool save(const std::string& path, std::string* error) const;
  bool load(const std::string& path, std::string* error);

 private:
  VoxelIndex blockOriginByDivision(const VoxelIndex& v) const;
  TsdfBlock* findOrCreateBlock(const VoxelIndex& block_origin);  // blockForUpdate() past its cache
  std::uint64_t blockKeyOf(const VoxelIndex& block_origin) const;
  bool blockInRange(const VoxelIndex& block_origin) const;

  TsdfMapParams params_;
  VoxelLayout layout_;
  int block_shift_ = -1;  // log2(voxels_per_side) for powers of two (shifts, not divisions)
  std::unordered_map<std::uint64_t, std::unique_ptr<TsdfBlock>> blocks_;
  std::vector<std::pair<std::uint64_t, TsdfBlock*>> ordered_;  // the same blocks, by key
  // One-entry cache for updates: rays touch the same block many times in a row.
  VoxelIndex cached_origin_ = VoxelIndex::Zero();
  TsdfBlock* cached_block_ = nullptr;  // the block at cached_origin_; nullptr: nothing kept
};

}  // namespace fruit_shape_completion
