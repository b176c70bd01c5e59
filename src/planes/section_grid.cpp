#include "blockmap/planes/section_grid.hpp"

#include <algorithm>
#include <array>

#include "blockmap/core/check.hpp"
#include "blockmap/core/merge_in_place.hpp"

namespace blockmap::planes {

void SectionGrid::init(Arena& arena, std::size_t max_blocks, std::uint32_t blocks_per_section,
                       double block_size_m) {
  BLOCKMAP_CHECK_MSG(max_blocks >= 1 && blocks_per_section >= 1 && blocks_per_section <= 4,
                     "bad section geometry");
  blocks_per_section_ = blocks_per_section;
  block_size_m_ = block_size_m;
  blocks_ = arena.allocate_array<KeyedBlock>(max_blocks, "planes.section_grid");
  listed_key_ = arena.allocate_array<CellKey>(max_blocks, "planes.section_grid");
  std::fill(listed_key_.begin(), listed_key_.end(), kNoCell);
  listed_count_ = 0;
  // Every block lies in k^3 sections, so there are at most k^3 sections per block, and as
  // many section-block pairs.
  const std::size_t pairs =
      max_blocks * blocks_per_section * blocks_per_section * blocks_per_section;
  sections_ = arena.allocate_array<CellKey>(pairs, "planes.section_grid");
  section_first_ = arena.allocate_array<std::uint32_t>(pairs + 1, "planes.section_grid");
  section_blocks_ = arena.allocate_array<std::uint32_t>(pairs, "planes.section_grid");
  section_first_[0] = 0;
}

std::size_t SectionGrid::arena_bytes(std::size_t max_blocks,
                                     std::uint32_t blocks_per_section) noexcept {
  const std::size_t pairs =
      max_blocks * blocks_per_section * blocks_per_section * blocks_per_section;
  return max_blocks * (sizeof(KeyedBlock) + sizeof(CellKey)) + pairs * sizeof(CellKey) +
         (2 * pairs + 1) * sizeof(std::uint32_t) +
         std::size_t{320};  // five allocations, 64-byte aligned
}

void SectionGrid::build(const VoxelGrid& grid) noexcept {
  counters_ = Counters{};
  merge_shifted_block_lists(list_occupied_blocks(grid));
}

std::size_t SectionGrid::list_occupied_blocks(const VoxelGrid& grid) noexcept {
  // Between two extractions a few blocks come or go: last time's sorted list keeps the ones
  // still there (same index, same key, samples in it), and the new ones, sorted apart at the
  // far end of the array, are merged in from the back. Keys are unique, so the list is the
  // one a sort of every block gives.
  const auto by_key = [](const KeyedBlock& a, const KeyedBlock& b) { return a.key < b.key; };
  const auto occupied = [&grid](std::size_t block) { return grid.block_range(block).count > 0; };
  if (grid.block_count() > listed_key_.size()) {
    return list_every_block(grid, listed_count_);  // more blocks than room: as many as fit
  }
  std::size_t kept = 0;
  for (std::size_t i = 0; i < listed_count_; ++i) {
    const KeyedBlock entry = blocks_[i];
    if (entry.block < grid.block_count() && grid.block_key(entry.block) == entry.key &&
        occupied(entry.block)) {
      blocks_[kept++] = entry;
    } else {
      listed_key_[entry.block] = kNoCell;
    }
  }
  const std::size_t end = blocks_.size();
  std::size_t fresh = 0;
  for (std::size_t block = 0; block < grid.block_count(); ++block) {
    if (!occupied(block) || listed_key_[block] == grid.block_key(block)) {
      continue;
    }
    if (kept + 2 * (fresh + 1) > end) {
      return list_every_block(grid, kept);  // no room to merge in place
    }
    blocks_[end - ++fresh] = KeyedBlock{grid.block_key(block), static_cast<std::uint32_t>(block)};
    listed_key_[block] = grid.block_key(block);
  }
  std::sort(blocks_.begin() + static_cast<std::ptrdiff_t>(end - fresh), blocks_.end(), by_key);
  merge_back_into_front(blocks_, kept, fresh, by_key);
  listed_count_ = kept + fresh;
  return listed_count_;
}

std::size_t SectionGrid::list_every_block(const VoxelGrid& grid, std::size_t listed) noexcept {
  for (std::size_t i = 0; i < listed; ++i) {
    listed_key_[blocks_[i].block] = kNoCell;
  }
  std::size_t block_count = 0;
  for (std::size_t block = 0; block < grid.block_count(); ++block) {
    if (grid.block_range(block).count > 0 && block_count < blocks_.size()) {
      blocks_[block_count++] = KeyedBlock{grid.block_key(block), static_cast<std::uint32_t>(block)};
    }
  }
  std::sort(blocks_.begin(), blocks_.begin() + static_cast<std::ptrdiff_t>(block_count),
            [](const KeyedBlock& a, const KeyedBlock& b) { return a.key < b.key; });
  // What is listed is kept for the next build only when every block had room.
  const bool complete = grid.block_count() <= listed_key_.size();
  for (std::size_t i = 0; complete && i < block_count; ++i) {
    listed_key_[blocks_[i].block] = blocks_[i].key;
  }
  listed_count_ = complete ? block_count : 0;
  return block_count;
}

void SectionGrid::merge_shifted_block_lists(std::size_t block_count) noexcept {
  // A section starting at block s covers blocks s .. s + k - 1, so the sections that hold
  // samples start at b - o for every occupied block b and offset o in {0 .. k-1}^3. For each
  // o, the keys b - o are as sorted as the blocks (a packed key minus a small offset has no
  // borrow between fields): merging the k^3 shifted lists gives the sections in key order,
  // each once, without sorting k^3 times as many keys.
  const std::uint32_t k = blocks_per_section_;
  std::array<CellKey, 64> offsets{};
  std::array<std::size_t, 64> next{};
  std::size_t lists = 0;
  for (std::uint32_t dx = 0; dx < k; ++dx) {
    for (std::uint32_t dy = 0; dy < k; ++dy) {
      for (std::uint32_t dz = 0; dz < k; ++dz) {
        offsets[lists++] = (CellKey{dx} << 42) | (CellKey{dy} << 21) | CellKey{dz};
      }
    }
  }
  section_count_ = 0;
  std::uint32_t pairs = 0;
  for (;;) {
    CellKey lowest = kNoCell;
    for (std::size_t list = 0; list < lists; ++list) {
      if (next[list] < block_count) {
        lowest = std::min(lowest, blocks_[next[list]].key - offsets[list]);
      }
    }
    if (lowest == kNoCell) {
      return;
    }
    // The heads equal to the section are its blocks, one per offset, in offset order.
    const bool room = section_count_ < sections_.size();
    for (std::size_t list = 0; list < lists; ++list) {
      if (next[list] < block_count && blocks_[next[list]].key - offsets[list] == lowest) {
        if (room) {
          section_blocks_[pairs++] = blocks_[next[list]].block;
        }
        ++next[list];
      }
    }
    if (!room) {
      ++counters_.sections_dropped_full;
      continue;
    }
    sections_[section_count_++] = lowest;
    section_first_[section_count_] = pairs;
  }
}

std::size_t SectionGrid::gather(const VoxelGrid& grid, std::span<const std::uint32_t> blocks,
                                std::span<std::uint32_t> out) noexcept {
  std::size_t count = 0;
  for (const std::uint32_t block : blocks) {
    const VoxelGrid::BlockRange range = grid.block_range(block);
    for (std::uint32_t id = range.first; id < range.first + range.count; ++id) {
      if (count == out.size()) {
        ++counters_.voxels_dropped_full;
        continue;
      }
      out[count++] = id;
    }
  }
  return count;
}

Eigen::Vector3f SectionGrid::centre_m(CellKey section) const noexcept {
  const auto s = unpack_cell(section);
  const double half = 0.5 * blocks_per_section_;
  return ((s.cast<double>().array() + half) * block_size_m_).matrix().cast<float>();
}

std::span<const CellKey, 13> SectionGrid::later_neighbour_offsets() noexcept {
  static constexpr std::array<CellKey, 13> kOffsets = [] {
    std::array<CellKey, 13> offsets{};
    std::size_t count = 0;
    const CellKey origin = pack_cell(0, 0, 0);
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
          const CellKey other = pack_cell(dx, dy, dz);
          if (other > origin) {
            offsets[count++] = other - origin;
          }
        }
      }
    }
    return offsets;
  }();
  return kOffsets;
}

}  // namespace blockmap::planes
