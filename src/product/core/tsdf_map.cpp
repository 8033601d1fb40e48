#include <fruit_shape_completion/tsdf_map.h>
#include <fruit_shape_completion/atomic_file.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <new>
#include <fstream>
#include <sstream>
#include <stdexcept>


namespace fruit_shape_completion {

namespace {
std::int64_t floorDiv(std::int64_t a, std::int64_t b) {
  std::int64_t q = a / b;
  if ((a % b != 0) && ((a < 0) != (b < 0))) --q;
  return q;
}
constexpr char kMagic[8] = {'F', 'S', 'C', 'T', 'S', 'D', 'F', '1'};
}  // namespace

void TsdfMapParams::validate() const {
  // Bounded so voxel indices stay far from int64 overflow (the map itself ends at +-2^20 blocks,
  // 268 km at 4 mm voxels and 64 per block: blockInRange).
  if (!(voxel_size >= 1e-4 && voxel_size <= 10.0))
    throw std::invalid_argument("tsdf voxel_size must be in [0.0001, 10] m");
  if (voxels_per_side < 1 || voxels_per_side > kMaxVoxelsPerSide)
    throw std::invalid_argument("tsdf voxels_per_side must be in 1.." + std::to_string(kMaxVoxelsPerSide));
  if (!(memory_budget_mb > 0.0) || !std::isfinite(memory_budget_mb) || maxBlocks() < 1) {
    std::ostringstream os;
    os << "tsdf memory_budget_mb (" << memory_budget_mb << ") must hold at least one block of "
       << static_cast<double>(blockBytes()) / 1048576.0 << " MiB";
    throw std::invalid_argument(os.str());
  }
  if (use_crop_box && !(crop_min.array() < crop_max.array()).all())
    throw std::invalid_argument("tsdf crop box must have crop_min < crop_max on every axis");
}

std::size_t TsdfMapParams::blockBytes() const {
  const std::size_t n = static_cast<std::size_t>(std::max(1, voxels_per_side));
  return sizeof(TsdfBlock) + n * n * n * sizeof(TsdfVoxel) + (n * n * n + 63) / 64 * 8;
}

std::size_t TsdfMapParams::maxBlocks() const {
  if (!(memory_budget_mb > 0.0) || !std::isfinite(memory_budget_mb)) return 0;
  return static_cast<std::size_t>(std::min(1e12, memory_budget_mb * 1048576.0 / static_cast<double>(blockBytes())));
}

namespace {
std::uint64_t nextEpoch() {
  static std::atomic<std::uint64_t> epochs{0};
  return ++epochs;
}
}  // namespace

TsdfMap::TsdfMap(const TsdfMapParams& params) : params_(params), configured_(params), epoch_(nextEpoch()) {
  params_.validate();
  max_blocks_ = params_.maxBlocks();
}

bool TsdfMap::insideCropBox(const Eigen::Vector3d& p) const {
  return !params_.use_crop_box ||
         ((p.array() >= params_.crop_min.array()).all() && (p.array() <= params_.crop_max.array()).all());
}

TsdfBlock::TsdfBlock(const VoxelIndex& o, int n)
    : origin(o),
      side(n),
      voxels(static_cast<TsdfVoxel*>(std::calloc(static_cast<std::size_t>(n) * n * n, sizeof(TsdfVoxel)))),
      observed_bits((static_cast<std::size_t>(n) * n * n + 63) / 64, 0) {
  // All-zero bytes are a voxel never observed (distance 0, weight 0).
  if (!voxels) throw std::bad_alloc();
}

std::size_t TsdfBlock::observedCount() const {
  std::size_t n = 0;
  for (std::uint64_t w : observed_bits) n += static_cast<std::size_t>(__builtin_popcountll(w));
  return n;
}

VoxelIndex TsdfMap::blockOriginOf(const VoxelIndex& v) const {
  const std::int64_t n = params_.voxels_per_side;
  return VoxelIndex(floorDiv(v.x(), n) * n, floorDiv(v.y(), n) * n, floorDiv(v.z(), n) * n);
}

std::uint64_t TsdfMap::blockKeyOf(const VoxelIndex& o) const {
  return packCellKey(o / static_cast<std::int64_t>(params_.voxels_per_side));  // o is a multiple of the side
}

const TsdfVoxel* TsdfMap::voxel(const VoxelIndex& v) const {
  // No use of the update cache here: const lookups stay safe from concurrent readers.
  const VoxelIndex origin = blockOriginOf(v);
  if (!blockInRange(origin)) return nullptr;
  const auto it = blocks_.find(blockKeyOf(origin));
  if (it == blocks_.end()) return nullptr;
  const VoxelIndex l = v - origin;
  return &it->second->voxels[it->second->indexOf(static_cast<int>(l.x()), static_cast<int>(l.y()), static_cast<int>(l.z()))];
}

bool TsdfMap::blockAllowed(const VoxelIndex& origin) const {
  if (!blockInRange(origin)) return false;
  if (!params_.use_crop_box) return true;
  const double vs = params_.voxel_size;
  const Eigen::Vector3d lo = origin.cast<double>() * vs;
  const Eigen::Vector3d hi = lo + Eigen::Vector3d::Constant(params_.voxels_per_side * vs);
  return !((hi.array() < params_.crop_min.array()).any() || (lo.array() > params_.crop_max.array()).any());
}

bool TsdfMap::blockInRange(const VoxelIndex& origin) const {
  // Block keys hold 21 bits per axis: beyond +-2^20 blocks two places would share a block.
  const std::int64_t limit = static_cast<std::int64_t>(params_.voxels_per_side) * ((std::int64_t(1) << 20) - 1);
  // No abs(): abs(INT64_MIN) is undefined and in practice stays negative.
  return (origin.array() >= -limit).all() && (origin.array() <= limit).all();
}

TsdfBlock* TsdfMap::blockForUpdate(const VoxelIndex& origin) {
  if (cached_block_ != nullptr && origin == cached_origin_) {
    cached_block_->revision = ++revision_;
    logUpdate(cached_block_);
    return cached_block_;
  }
  if (!blockInRange(origin)) return nullptr;
  const std::uint64_t key = blockKeyOf(origin);
  auto it = blocks_.find(key);
  if (it == blocks_.end()) {
    if (!blockAllowed(origin) || atBudget()) return nullptr;
    it = blocks_.emplace(key, std::make_unique<TsdfBlock>(origin, params_.voxels_per_side)).first;
  }
  cached_origin_ = origin;
  cached_block_ = it->second.get();
  cached_block_->revision = ++revision_;
  logUpdate(cached_block_);
  return cached_block_;
}

std::uint64_t TsdfMap::markUpdates() const {
  // Readers mark once per look: generations before the last few are dropped once the log
  // outgrows the map, and a reader that old visits every block instead.
  if (update_log_.size() > 2 * blocks_.size() + 4096) {
    const std::uint64_t keep_from = log_generation_ > 4 ? log_generation_ - 4 : 1;
    update_log_.erase(update_log_.begin(), firstLoggedIn(keep_from));
    log_start_ = std::max(log_start_, keep_from);
  }
  return ++log_generation_;
}

bool TsdfMap::setVoxel(const VoxelIndex& v, const TsdfVoxel& value) {
  if (!insideCropBox(voxelCenter(v))) return false;
  const VoxelIndex origin = blockOriginOf(v);
  TsdfBlock* block = blockForUpdate(origin);
  if (block == nullptr) return false;
  const VoxelIndex l = v - origin;
  const std::uint32_t idx = block->indexOf(static_cast<int>(l.x()), static_cast<int>(l.y()), static_cast<int>(l.z()));
  block->voxels[idx] = value;
  if (value.weight > 0.0f) block->markObserved(idx);
  return true;
}

std::size_t TsdfMap::observedVoxelCount() const {
  std::size_t n = 0;
  for (const auto& kb : blocks_) n += kb.second->observedCount();
  return n;
}

std::size_t TsdfMap::memoryBytes() const {
  std::size_t bytes = sizeof(*this);
  for (const auto& kb : blocks_)
    bytes += sizeof(TsdfBlock) + blockVoxels() * sizeof(TsdfVoxel) +
             kb.second->observed_bits.size() * sizeof(std::uint64_t) + 6 * sizeof(void*);
  return bytes;
}

void TsdfMap::clear() {
  resetLog();
  blocks_.clear();
  // A loaded file's block side and budget belonged to that map: an empty one starts as configured.
  params_ = configured_;
  max_blocks_ = params_.maxBlocks();
  cached_block_ = nullptr;
  epoch_ = nextEpoch();
}

void TsdfMap::serialize(std::string* bytes) const {
  std::string& out = *bytes;
  out.clear();
  auto put = [&out](const void* p, std::size_t n) { out.append(static_cast<const char*>(p), n); };
  const std::uint32_t version = 1;
  const std::uint32_t vps = params_.voxels_per_side;
  const std::uint64_t count = blocks_.size();
  std::size_t observed = 0;
  for (const auto& kb : blocks_) observed += kb.second->observedCount();
  out.reserve(32 + blocks_.size() * 28 + observed * 12);
  put(kMagic, 8);
  put(&version, 4);
  put(&params_.voxel_size, 8);
  put(&vps, 4);
  put(&count, 8);
  for (const auto& kb : blocks_) {
    const TsdfBlock& b = *kb.second;
    const std::int64_t origin[3] = {b.origin.x(), b.origin.y(), b.origin.z()};
    const std::uint32_t n = static_cast<std::uint32_t>(b.observedCount());
    put(origin, sizeof(origin));
    put(&n, 4);
    b.forEachObserved([&](std::uint32_t idx) {
      put(&idx, 4);
      put(&b.voxels[idx].distance, 4);
      put(&b.voxels[idx].weight, 4);
    });
  }
}

bool TsdfMap::save(const std::string& path, std::string* error) const {
  std::string bytes;
  serialize(&bytes);
  return writeFileAtomically(path, bytes, error);
}

bool TsdfMap::load(const std::string& path, std::string* error, std::string* rest) {
  auto fail = [&](const std::string& what) {
    if (error) *error = path + ": " + what;
    return false;
  };
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail("cannot open file");
  auto get = [&in](void* p, std::size_t n) { return static_cast<bool>(in.read(static_cast<char*>(p), n)); };
  char magic[8];
  std::uint32_t version = 0, vps = 0;
  double voxel_size = 0;
  std::uint64_t count = 0;
  if (!get(magic, 8) || std::memcmp(magic, kMagic, 8) != 0) return fail("not a TSDF map file (bad magic)");
  if (!get(&version, 4) || version != 1) return fail("unsupported TSDF map file version");
  if (!get(&voxel_size, 8) || !get(&vps, 4) || !get(&count, 8)) return fail("truncated header");
  // A file's block costs vps^3 voxels of memory for as little as 12 bytes of file: a block side
  // beyond the largest a map may have is no map this package writes.
  if (vps > static_cast<std::uint32_t>(TsdfMapParams::kMaxVoxelsPerSide))
    return fail("bad header: voxels_per_side " + std::to_string(vps) + " exceeds " +
                std::to_string(TsdfMapParams::kMaxVoxelsPerSide));
  TsdfMapParams p = params_;
  p.voxel_size = voxel_size;
  p.voxels_per_side = static_cast<int>(vps);
  try {
    p.validate();
  } catch (const std::exception& e) {
    return fail(std::string("bad header: ") + e.what());
  }
  if (count > static_cast<std::uint64_t>(p.maxBlocks()))
    return fail("file holds " + std::to_string(count) + " blocks, more than memory_budget_mb allows (" +
                std::to_string(p.maxBlocks()) + ")");
  try {
    TsdfMap loaded(p);
    const std::uint64_t voxels = static_cast<std::uint64_t>(vps) * vps * vps;
    for (std::uint64_t b = 0; b < count; ++b) {
      std::int64_t origin[3];
      std::uint32_t n = 0;
      if (!get(origin, sizeof(origin)) || !get(&n, 4)) return fail("truncated block header");
      if (n > voxels) return fail("block lists more voxels than it has");
      for (int k = 0; k < 3; ++k)
        if (origin[k] % static_cast<std::int64_t>(vps) != 0) return fail("misaligned block origin");
      if (!loaded.blockInRange(VoxelIndex(origin[0], origin[1], origin[2]))) return fail("block origin out of range");
      for (std::uint32_t i = 0; i < n; ++i) {
        std::uint32_t idx;
        TsdfVoxel v;
        if (!get(&idx, 4) || !get(&v.distance, 4) || !get(&v.weight, 4)) return fail("truncated voxel data");
        if (idx >= voxels || !std::isfinite(v.distance) || !(v.weight > 0.0f) || !std::isfinite(v.weight))
          return fail("corrupt voxel data");
        const VoxelIndex g(origin[0] + idx % vps, origin[1] + (idx / vps) % vps, origin[2] + idx / (vps * vps));
        if (!loaded.setVoxel(g, v)) return fail("voxel outside the crop box or block limit");
      }
    }
    if (rest) {
      rest->assign(kMaxRestBytes + 1, '\0');
      in.read(&(*rest)[0], static_cast<std::streamsize>(rest->size()));
      rest->resize(static_cast<std::size_t>(in.gcount()));
    }
    resetLog();
    blocks_.swap(loaded.blocks_);
    params_ = p;  // the file's block side may differ from the map's, and with it the blocks the budget holds
    max_blocks_ = p.maxBlocks();
    cached_block_ = nullptr;
    epoch_ = nextEpoch();
    revision_ = loaded.revision_;
    return true;
  } catch (const std::bad_alloc&) {
    return fail("out of memory while loading; the map in memory is unchanged");
  }
}

}  // namespace fruit_shape_completion
