// Voxel and block coordinates packed into one 64-bit key, and a fixed-capacity index from
// keys to 32-bit values: the tables of VoxelGrid, VoxelWindow and the section grid.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/core/linear_probing.hpp"

namespace blockmap::planes {

// Integer voxel coordinates packed into 64 bits, 21 bits per axis: +-1,048,575 voxels.
using CellKey = std::uint64_t;
inline constexpr std::int64_t kCellKeyBias = std::int64_t{1} << 20;

[[nodiscard]] constexpr CellKey pack_cell(std::int64_t x, std::int64_t y, std::int64_t z) noexcept {
  return (static_cast<CellKey>(x + kCellKeyBias) << 42) |
         (static_cast<CellKey>(y + kCellKeyBias) << 21) | static_cast<CellKey>(z + kCellKeyBias);
}
[[nodiscard]] inline Eigen::Matrix<std::int64_t, 3, 1> unpack_cell(CellKey key) noexcept {
  constexpr CellKey kMask = (CellKey{1} << 21) - 1;
  return {static_cast<std::int64_t>((key >> 42) & kMask) - kCellKeyBias,
          static_cast<std::int64_t>((key >> 21) & kMask) - kCellKeyBias,
          static_cast<std::int64_t>(key & kMask) - kCellKeyBias};
}
[[nodiscard]] constexpr bool cell_in_range(std::int64_t x, std::int64_t y,
                                           std::int64_t z) noexcept {
  return x > -kCellKeyBias && x < kCellKeyBias && y > -kCellKeyBias && y < kCellKeyBias &&
         z > -kCellKeyBias && z < kCellKeyBias;
}

// The first slot to probe for `key` in a table of mask + 1 slots (shift = 64 - log2 slots).
// Cells of one 4 x 4 x 4 block hash to 64 consecutive slots: the neighbours of a cell, looked
// up together, share cache lines instead of each costing a miss.
[[nodiscard]] constexpr std::size_t block_local_home_slot(CellKey key, std::uint32_t shift,
                                                          std::size_t mask) noexcept {
  constexpr CellKey kLowBits = (CellKey{3} << 42) | (CellKey{3} << 21) | CellKey{3};
  const CellKey local = (((key >> 42) & 3) << 4) | (((key >> 21) & 3) << 2) | (key & 3);
  const CellKey block = key & ~kLowBits;
  return static_cast<std::size_t>(((block * 0x9E3779B97F4A7C15ull) >> shift) + local) & mask;
}

// A fixed-capacity map from cell keys to 32-bit values (open addressing, linear probing).
class CellIndex {
 public:
  static constexpr std::uint32_t kAbsent = 0xFFFFFFFFu;
  void init(Arena& arena, std::size_t max_keys, const char* owner);
  void clear() noexcept;
  // The value of `key`, or kAbsent.
  [[nodiscard]] std::uint32_t find(CellKey key) const noexcept {
    const std::size_t slot = probe(
        home_slot(key), mask_, [this](std::size_t at) { return slots_[at].value == kAbsent; },
        [this, key](std::size_t at) { return slots_[at].key == key; });
    return slots_[slot].value;
  }
  // The slot of `key`, inserting it with `value` when absent; false when full.
  bool find_or_insert(CellKey key, std::uint32_t value, std::uint32_t& found) noexcept;
  // Takes `key` out (nothing when absent).
  void erase(CellKey key) noexcept;
  [[nodiscard]] std::size_t size() const noexcept { return size_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept { return slots_.size_bytes(); }
  // Bytes init() takes from the arena for `max_keys`.
  [[nodiscard]] static std::size_t arena_bytes(std::size_t max_keys) noexcept;

 private:
  struct Slot {
    CellKey key = 0;
    std::uint32_t value = kAbsent;
  };
  [[nodiscard]] std::size_t home_slot(CellKey key) const noexcept {
    return block_local_home_slot(key, shift_, mask_);
  }
  std::span<Slot> slots_;
  std::uint32_t shift_ = 64;
  std::size_t mask_ = 0;
  std::size_t max_keys_ = 0;
  std::size_t size_ = 0;
};

// Marks an empty slot of the voxel table (a packed key never has its top bit set).
inline constexpr CellKey kNoCell = ~CellKey{0};

// Voxels are grouped in blocks of 4 x 4 x 4: a 64-bit mask says which cells of a block hold
// points, and a cell's bit is its position in the block.
inline constexpr std::int64_t kBlockEdge = 4;
[[nodiscard]] constexpr CellKey block_of_cell(std::int64_t x, std::int64_t y,
                                              std::int64_t z) noexcept {
  return pack_cell(x >> 2, y >> 2, z >> 2);  // arithmetic shift: floor division by 4
}
[[nodiscard]] constexpr std::uint32_t bit_in_block(std::int64_t x, std::int64_t y,
                                                   std::int64_t z) noexcept {
  return static_cast<std::uint32_t>(((x & 3) << 4) | ((y & 3) << 2) | (z & 3));
}

}  // namespace blockmap::planes
