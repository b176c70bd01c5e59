#include "blockmap/planes/section_grid.hpp"

#include <algorithm>
#include <array>

#include "blockmap/core/check.hpp"

namespace blockmap::planes {

void SectionGrid::init(Arena& arena, std::size_t max_blocks, std::uint32_t blocks_per_section,
                       double block_size_m) {
  BLOCKMAP_CHECK_MSG(max_blocks >= 1 && blocks_per_section >= 1 && blocks_per_section <= 4,
                     "bad section geometry");
  blocks_per_section_ = blocks_per_section;
  block_size_m_ = block_size_m;
  blocks_ = arena.allocate_array<CellKey>(max_blocks, "planes.section_grid");
  // Every block starts k^3 sections at most.
  sections_ = arena.allocate_array<CellKey>(
      max_blocks * blocks_per_section * blocks_per_section * blocks_per_section,
      "planes.section_grid");
}

std::size_t SectionGrid::arena_bytes(std::size_t max_blocks,
                                     std::uint32_t blocks_per_section) noexcept {
  return max_blocks * (1 + blocks_per_section * blocks_per_section * blocks_per_section) *
             sizeof(CellKey) +
         std::size_t{128};  // two allocations, 64-byte aligned
}

void SectionGrid::build(const VoxelGrid& grid) noexcept {
  counters_ = Counters{};
  std::size_t block_count = 0;
  for (std::size_t block = 0; block < grid.block_count(); ++block) {
    if (grid.block_range(block).count > 0 && block_count < blocks_.size()) {
      blocks_[block_count++] = grid.block_key(block);
    }
  }
  std::sort(blocks_.begin(), blocks_.begin() + static_cast<std::ptrdiff_t>(block_count));
  merge_shifted_block_lists(block_count);
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
  for (;;) {
    CellKey lowest = kNoCell;
    for (std::size_t list = 0; list < lists; ++list) {
      if (next[list] < block_count) {
        lowest = std::min(lowest, blocks_[next[list]] - offsets[list]);
      }
    }
    if (lowest == kNoCell) {
      return;
    }
    for (std::size_t list = 0; list < lists; ++list) {
      if (next[list] < block_count && blocks_[next[list]] - offsets[list] == lowest) {
        ++next[list];
      }
    }
    if (section_count_ == sections_.size()) {
      ++counters_.sections_dropped_full;
      continue;
    }
    sections_[section_count_++] = lowest;
  }
}

std::size_t SectionGrid::find_blocks(
    const VoxelGrid& grid, CellKey section,
    std::span<std::uint32_t, kMaxBlocksPerSection> out) const noexcept {
  const auto s = unpack_cell(section);
  const auto k = static_cast<std::int64_t>(blocks_per_section_);
  std::size_t count = 0;
  for (std::int64_t dx = 0; dx < k; ++dx) {
    for (std::int64_t dy = 0; dy < k; ++dy) {
      for (std::int64_t dz = 0; dz < k; ++dz) {
        const std::uint32_t block = grid.find_block(pack_cell(s.x() + dx, s.y() + dy, s.z() + dz));
        if (block != CellIndex::kAbsent) {
          out[count++] = block;
        }
      }
    }
  }
  return count;
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

std::size_t SectionGrid::later_neighbours(CellKey section,
                                          std::span<CellKey, 13> out) const noexcept {
  const auto s = unpack_cell(section);
  std::size_t count = 0;
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dz = -1; dz <= 1; ++dz) {
        const CellKey other = pack_cell(s.x() + dx, s.y() + dy, s.z() + dz);
        if (other > section) {
          out[count++] = other;
        }
      }
    }
  }
  return count;
}

}  // namespace blockmap::planes
