// The paper's small overlapping sections. Space is cut into blocks of section_stride_m (the
// voxel grid's 4 x 4 x 4 blocks); a section is a cube of k x k x k blocks (k = section_size /
// stride) and one starts at every block, so each point lies in k^3 sections and a plane that
// crosses a section border lies whole in a neighbouring section.
#pragma once

#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"
#include "blockmap/planes/voxel_grid.hpp"

namespace blockmap::planes {

class SectionGrid {
 public:
  struct Counters {
    std::uint64_t sections_dropped_full = 0;  // more sections than max_samples
    std::uint64_t voxels_dropped_full = 0;    // a section held more than its capacity
  };

  void init(Arena& arena, std::size_t max_blocks, std::uint32_t blocks_per_section,
            double block_size_m);
  [[nodiscard]] static std::size_t arena_bytes(std::size_t max_blocks,
                                               std::uint32_t blocks_per_section) noexcept;

  // Lists every section that holds a sample of `grid` (after its compact()), in key order.
  void build(const VoxelGrid& grid) noexcept;

  [[nodiscard]] std::span<const CellKey> sections() const noexcept {
    return sections_.first(section_count_);
  }
  // The indexes of the occupied blocks of sections()[index] (at most k^3 <= 64), in offset
  // order (x, then y, then z), as build() found them.
  [[nodiscard]] std::span<const std::uint32_t> blocks_of(std::size_t index) const noexcept {
    return section_blocks_.subspan(section_first_[index],
                                   section_first_[index + 1] - section_first_[index]);
  }
  // The samples of those blocks (ids into grid.voxels()), block by block; at most out.size().
  std::size_t gather(const VoxelGrid& grid, std::span<const std::uint32_t> blocks,
                     std::span<std::uint32_t> out) noexcept;
  [[nodiscard]] Eigen::Vector3f centre_m(CellKey section) const noexcept;
  // The sections that share a face, edge or corner with one and come later in key order
  // (each neighbouring pair once) are the section's key plus these offsets: the packed
  // coordinates have room, so an offset never carries into the next field. In the order
  // dx, dy, dz from -1 to 1.
  [[nodiscard]] static std::span<const CellKey, 13> later_neighbour_offsets() noexcept;
  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return blocks_.size_bytes() + listed_key_.size_bytes() + sections_.size_bytes() +
           section_first_.size_bytes() + section_blocks_.size_bytes();
  }

 private:
  // The occupied blocks of `grid`, sorted by key, in blocks_; returns their count.
  std::size_t list_occupied_blocks(const VoxelGrid& grid) noexcept;
  // The same, sorted afresh (`listed`: how many of blocks_ are listed now).
  std::size_t list_every_block(const VoxelGrid& grid, std::size_t listed) noexcept;
  void merge_shifted_block_lists(std::size_t block_count) noexcept;

  std::uint32_t blocks_per_section_ = 2;
  double block_size_m_ = 0.0;
  struct KeyedBlock {
    CellKey key = 0;
    std::uint32_t block = 0;  // its index in the voxel grid
  };
  std::span<KeyedBlock> blocks_;   // the occupied blocks, sorted by key
  std::size_t listed_count_ = 0;   // how many, as the last build() listed them
  std::span<CellKey> listed_key_;  // per block index: its key in blocks_, or kNoCell
  std::span<CellKey> sections_;
  // Section i's blocks are section_blocks_[section_first_[i], section_first_[i + 1]): the
  // merge sees them (the list heads equal to the section), so no lookup finds them again.
  std::span<std::uint32_t> section_first_;
  std::span<std::uint32_t> section_blocks_;
  std::size_t section_count_ = 0;
  Counters counters_;
};

}  // namespace blockmap::planes
