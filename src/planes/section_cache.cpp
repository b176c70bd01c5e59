#include "blockmap/planes/section_cache.hpp"

#include <algorithm>
#include <bit>
#include <cstring>

#include "blockmap/core/check.hpp"

namespace blockmap::planes {
namespace {

// One word into a running 64-bit hash (multiply and fold, as in MurmurHash3's finalizer): a
// signature that differs in any input bit differs almost surely.
constexpr std::uint64_t mixed(std::uint64_t hash, std::uint64_t word) noexcept {
  hash ^= word;
  hash *= 0xFF51AFD7ED558CCDULL;
  return hash ^ (hash >> 33);
}

std::uint64_t bits_of(float a, float b) noexcept {
  std::uint32_t low = 0;
  std::uint32_t high = 0;
  std::memcpy(&low, &a, sizeof(low));
  std::memcpy(&high, &b, sizeof(high));
  return (std::uint64_t{high} << 32) | low;
}

constexpr std::size_t kCodeWords = 4;  // 64 cells, a nibble each
constexpr std::uint64_t kNibbles = 0x1111111111111111ULL;

// The nibbles of `flags` (each 0 or 1 in its lowest bit) packed into 16 bits, nibble n to bit
// n: each step halves the gaps between the flags, without a branch per flag.
constexpr std::uint64_t packed_nibble_flags(std::uint64_t flags) noexcept {
  flags = (flags | (flags >> 3)) & 0x0303030303030303ULL;
  flags = (flags | (flags >> 6)) & 0x000F000F000F000FULL;
  flags = (flags | (flags >> 12)) & 0x000000FF000000FFULL;
  return (flags | (flags >> 24)) & 0xFFFFULL;
}
static_assert(packed_nibble_flags(0x1000000000000001ULL) == 0x8001ULL);
static_assert(packed_nibble_flags(0x0101010101010101ULL) == 0x5555ULL);

// The cells (a 64-bit block mask) whose nibble in `words` equals `code`.
std::uint64_t cells_with_code(const std::uint64_t* words, std::uint32_t code) noexcept {
  std::uint64_t cells = 0;
  for (std::size_t w = 0; w < kCodeWords; ++w) {
    // A nibble equal to code becomes 0 after the xor; folding each nibble's bits into its
    // lowest marks the non-zero ones. Nibble n of word w is cell 16 w + n.
    std::uint64_t diff = words[w] ^ (kNibbles * code);
    diff |= diff >> 1;
    diff |= diff >> 2;
    cells |= packed_nibble_flags(~diff & kNibbles) << (16 * w);
  }
  return cells;
}

std::uint64_t bits_of(double value) noexcept {
  std::uint64_t bits = 0;
  std::memcpy(&bits, &value, sizeof(bits));
  return bits;
}

std::uint64_t mixed(std::uint64_t hash, const Eigen::Vector3d& v) noexcept {
  return mixed(mixed(mixed(hash, bits_of(v.x())), bits_of(v.y())), bits_of(v.z()));
}

}  // namespace

std::uint64_t SectionCache::salt_of(std::span<const PlaneExclusion> exclusions) noexcept {
  std::uint64_t hash = exclusions.size() + 1;  // never 0, the salt of "none asked"
  for (const PlaneExclusion& e : exclusions) {
    hash = mixed(mixed(hash, e.normal), bits_of(e.cos_max_angle));
    hash = mixed(hash, bits_of(e.distance_m));
    for (const Eigen::Vector3d& origin : e.origins_m) {
      hash = mixed(hash, origin);
    }
  }
  return hash;
}

void SectionCache::init(Arena& arena, std::size_t max_blocks, std::size_t max_sections,
                        std::size_t max_section_planes) {
  BLOCKMAP_CHECK_MSG(max_blocks >= 1 && max_sections >= 1 && max_section_planes >= 1,
                     "section cache capacities must be >= 1");
  block_signatures_ = arena.allocate_array<std::uint64_t>(max_blocks, "planes.section_cache");
  block_keys_ = arena.allocate_array<CellKey>(max_blocks, "planes.section_cache");
  taken_cells_ = arena.allocate_array<std::uint64_t>(max_blocks, "planes.section_cache");
  taken_codes_ =
      arena.allocate_array<std::uint64_t>(max_blocks * kCodeWords, "planes.section_cache");
  entries_[0] = arena.allocate_array<Entry>(max_sections, "planes.section_cache");
  entries_[1] = arena.allocate_array<Entry>(max_sections, "planes.section_cache");
  kept_planes_ = arena.allocate_array<SectionPlane>(max_section_planes, "planes.section_cache");
  std::fill(taken_codes_.begin(), taken_codes_.end(), std::uint64_t{0});
  invalidate();
}

std::size_t SectionCache::arena_bytes(std::size_t max_blocks, std::size_t max_sections,
                                      std::size_t max_section_planes) noexcept {
  constexpr std::size_t kAlignment = Arena::kMaxPaddingBytes;
  return max_blocks * (3 + kCodeWords) * sizeof(std::uint64_t) + 2 * max_sections * sizeof(Entry) +
         max_section_planes * sizeof(SectionPlane) + 6 * kAlignment;
}

void SectionCache::invalidate() noexcept {
  std::fill_n(taken_codes_.begin(), block_count_ * kCodeWords, std::uint64_t{0});
  std::fill_n(block_keys_.begin(), block_count_, kNoCell);
  entry_count_[0] = 0;
  entry_count_[1] = 0;
  block_count_ = 0;
  valid_ = false;
  signatures_valid_ = false;
}

std::uint32_t SectionCache::offset_code(CellKey section, CellKey block_key) noexcept {
  const Eigen::Matrix<std::int64_t, 3, 1> offset = unpack_cell(block_key) - unpack_cell(section);
  return static_cast<std::uint32_t>(offset.x() * 4 + offset.y() * 2 + offset.z()) + 1;
}

std::uint64_t SectionCache::sign_block(const VoxelGrid& grid, std::uint32_t block) const noexcept {
  // Everything a section reads of a sample: where it is and its points (the sums), and what
  // the shape pass made of it.
  // Three independent lanes, joined at the end: each mix waits on the one before it in its
  // lane, so one lane of seven mixes per sample took seven multiplies' latency.
  std::uint64_t a = grid.block_key(block);
  std::uint64_t b = 0x9E3779B97F4A7C15ULL;
  std::uint64_t c = 0xC2B2AE3D27D4EB4FULL;
  const VoxelGrid::BlockRange range = grid.block_range(block);
  const std::span<const Voxel> voxels = grid.voxels();
  for (std::uint32_t id = range.first; id < range.first + range.count; ++id) {
    const Voxel& v = voxels[id];
    a = mixed(a, v.key ^ (std::uint64_t{v.point_count} << 40) ^
                     (std::uint64_t{static_cast<std::uint8_t>(v.shape)} << 36));
    b = mixed(b, bits_of(v.sum_m[0], v.sum_m[1]));
    c = mixed(c, bits_of(v.sum_m[2], v.sum_outer_m2[0]));
    a = mixed(a, bits_of(v.sum_outer_m2[1], v.sum_outer_m2[2]));
    b = mixed(b, bits_of(v.sum_outer_m2[3], v.sum_outer_m2[4]));
    c = mixed(c, bits_of(v.sum_outer_m2[5], v.axis.x()));
    a = mixed(a, bits_of(v.axis.y(), v.axis.z()));
  }
  return mixed(mixed(a, b), c);
}

void SectionCache::begin(const VoxelGrid& grid, std::uint64_t salt) noexcept {
  if (salt != salt_) {
    // Every section may come out otherwise: what they took is not known any more either.
    salt_ = salt;
    invalidate();
  }
  BLOCKMAP_CHECK_MSG(grid.block_count() <= block_signatures_.size(),
                     "section cache sized for fewer blocks than the grid holds");
  // Indices new since last time start with kNoCell.
  std::fill(
      block_keys_.begin() + static_cast<std::ptrdiff_t>(block_count_),
      block_keys_.begin() + static_cast<std::ptrdiff_t>(std::max(block_count_, grid.block_count())),
      kNoCell);
  block_count_ = std::max(block_count_, grid.block_count());
  for (std::uint32_t block = 0; block < grid.block_count(); ++block) {
    // An erased block's index, empty or holding another block: nothing of it was taken.
    const bool other_block =
        grid.live_mask(block) == 0 || block_keys_[block] != grid.block_key(block);
    if (other_block) {
      forget_block(block);
      block_keys_[block] = grid.live_mask(block) == 0 ? kNoCell : grid.block_key(block);
    }
    // Signing reads every sample; a block whose samples are as they were keeps its signature.
    if (!signatures_valid_ || other_block || grid.samples_changed(block)) {
      block_signatures_[block] = sign_block(grid, block);
    }
#ifndef NDEBUG
    BLOCKMAP_CHECK_MSG(block_signatures_[block] == sign_block(grid, block),
                       "a block's samples changed where the grid said they had not");
#endif
  }
  signatures_valid_ = true;
  std::fill_n(taken_cells_.begin(), grid.block_count(), std::uint64_t{0});
  current_ ^= 1;
  entry_count_[current_] = 0;
  cursor_ = 0;
}

void SectionCache::forget_block(std::uint32_t block) noexcept {
  std::fill_n(taken_codes_.begin() + static_cast<std::ptrdiff_t>(block * kCodeWords), kCodeWords,
              std::uint64_t{0});
}

std::uint64_t SectionCache::signature(CellKey section,
                                      std::span<const std::uint32_t> blocks) const noexcept {
  std::uint64_t hash = mixed(salt_, section);
  for (const std::uint32_t block : blocks) {
    hash = mixed(hash, block_signatures_[block]);
    hash = mixed(hash, taken_cells_[block]);
  }
  return hash;
}

const SectionCache::Entry* SectionCache::previous(CellKey section) noexcept {
  if (!valid_) {
    return nullptr;
  }
  const std::span<const Entry> before = entries_[current_ ^ 1].first(entry_count_[current_ ^ 1]);
  while (cursor_ < before.size() && before[cursor_].section < section) {
    ++cursor_;
  }
  return cursor_ < before.size() && before[cursor_].section == section ? &before[cursor_] : nullptr;
}

std::uint64_t SectionCache::taken_by(CellKey section, std::uint32_t block,
                                     CellKey block_key) const noexcept {
  return cells_with_code(&taken_codes_[block * kCodeWords], offset_code(section, block_key));
}

std::uint64_t SectionCache::retake(CellKey section, std::uint32_t block,
                                   CellKey block_key) noexcept {
  // Their nibbles already hold this section's offset: only this detection's mask is new.
  const std::uint64_t cells = taken_by(section, block, block_key);
  taken_cells_[block] |= cells;
  return cells;
}

void SectionCache::forget_taken(CellKey section, std::span<const std::uint32_t> blocks,
                                const VoxelGrid& grid) noexcept {
  for (const std::uint32_t block : blocks) {
    const std::uint32_t code = offset_code(section, grid.block_key(block));
    std::uint64_t* words = &taken_codes_[block * kCodeWords];
    for (std::uint64_t cells = cells_with_code(words, code); cells != 0; cells &= cells - 1) {
      const auto cell = static_cast<std::uint32_t>(std::countr_zero(cells));
      words[cell / 16] &= ~(std::uint64_t{0xF} << (4 * (cell % 16)));
    }
  }
}

void SectionCache::take(CellKey section, std::uint32_t block, CellKey block_key,
                        std::uint32_t cell_bit) noexcept {
  taken_cells_[block] |= std::uint64_t{1} << cell_bit;
  std::uint64_t& word = taken_codes_[block * kCodeWords + cell_bit / 16];
  const std::uint32_t shift = 4 * (cell_bit % 16);
  word = (word & ~(std::uint64_t{0xF} << shift)) |
         (std::uint64_t{offset_code(section, block_key)} << shift);
}

void SectionCache::record(const Entry& entry) noexcept {
  std::size_t& count = entry_count_[current_];
  if (count == entries_[current_].size()) {
    ++counters_.sections_not_kept;
    return;
  }
  entries_[current_][count++] = entry;
}

void SectionCache::end(std::span<const SectionPlane> planes, bool complete) noexcept {
  // The planes fit: the merger holds as many as kept_planes_ does.
  std::copy_n(planes.begin(), std::min(planes.size(), kept_planes_.size()), kept_planes_.begin());
  valid_ = complete && planes.size() <= kept_planes_.size();
  if (!valid_) {
    // A section that took samples without keeping its planes must not be replayed.
    std::fill_n(taken_codes_.begin(), block_count_ * kCodeWords, std::uint64_t{0});
    entry_count_[current_] = 0;
  }
}

std::size_t SectionCache::memory_bytes() const noexcept {
  return block_signatures_.size_bytes() + block_keys_.size_bytes() + taken_cells_.size_bytes() +
         taken_codes_.size_bytes() + entries_[0].size_bytes() + entries_[1].size_bytes() +
         kept_planes_.size_bytes();
}

}  // namespace blockmap::planes
