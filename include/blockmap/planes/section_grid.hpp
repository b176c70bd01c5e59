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
  // The indexes of the occupied blocks of a section (at most 64: k <= 4).
  static constexpr std::size_t kMaxBlocksPerSection = 64;
  [[nodiscard]] std::size_t find_blocks(
      const VoxelGrid& grid, CellKey section,
      std::span<std::uint32_t, kMaxBlocksPerSection> out) const noexcept;
  // The samples of those blocks (ids into grid.voxels()), block by block; at most out.size().
  std::size_t gather(const VoxelGrid& grid, std::span<const std::uint32_t> blocks,
                     std::span<std::uint32_t> out) noexcept;
  [[nodiscard]] Eigen::Vector3f centre_m(CellKey section) const noexcept;
  // The sections that share a face, edge or corner with this one and come later in key
  // order (each neighbouring pair once).
  [[nodiscard]] std::size_t later_neighbours(CellKey section,
                                             std::span<CellKey, 13> out) const noexcept;
  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return blocks_.size_bytes() + sections_.size_bytes();
  }

 private:
  void merge_shifted_block_lists(std::size_t block_count) noexcept;

  std::uint32_t blocks_per_section_ = 2;
  double block_size_m_ = 0.0;
  std::span<CellKey> blocks_;  // the occupied blocks' keys, sorted
  std::span<CellKey> sections_;
  std::size_t section_count_ = 0;
  Counters counters_;
};

}  // namespace blockmap::planes
