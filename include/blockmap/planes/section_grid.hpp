// The paper's small overlapping sections. Space is cut into blocks of section_stride_m; a
// section is a cube of k x k x k blocks (k = section_size / stride) and one starts at every
// block, so each point lies in k^3 sections and a plane that crosses a section border lies
// whole in a neighbouring section.
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

  void init(Arena& arena, std::size_t max_voxels, std::uint32_t voxels_per_block,
            std::uint32_t blocks_per_section, double voxel_size_m);

  // Indexes the voxels by block and lists every section that holds any, in key order.
  void build(const VoxelGrid& grid) noexcept;

  // Every voxel index once, grouped by block (neighbours close together).
  [[nodiscard]] std::span<const std::uint32_t> voxel_order() const noexcept {
    return voxel_order_.first(voxel_count_);
  }
  [[nodiscard]] std::span<const CellKey> sections() const noexcept {
    return sections_.first(section_count_);
  }
  // The voxels of a section (indices into the grid's voxels), in a fixed order; at most
  // out.size() of them.
  std::size_t gather(CellKey section, std::span<std::uint32_t> out) noexcept;
  [[nodiscard]] Eigen::Vector3f centre_m(CellKey section) const noexcept;
  // The sections that share a face, edge or corner with this one and come later in key
  // order (each neighbouring pair once).
  [[nodiscard]] std::size_t later_neighbours(CellKey section,
                                             std::span<CellKey, 13> out) const noexcept;
  [[nodiscard]] const Counters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return order_.size_bytes() + voxel_order_.size_bytes() + block_range_.size_bytes() +
           sections_.size_bytes() + block_index_.memory_bytes();
  }

 private:
  struct BlockVoxel {
    CellKey block = 0;
    std::uint32_t voxel = 0;
  };
  struct Range {
    std::uint32_t begin = 0;
    std::uint32_t end = 0;
  };

  [[nodiscard]] CellKey block_of(CellKey voxel) const noexcept;

  std::uint32_t voxels_per_block_ = 1;
  std::uint32_t blocks_per_section_ = 2;
  double block_size_m_ = 0.0;
  std::span<BlockVoxel> order_;
  std::span<std::uint32_t> voxel_order_;
  std::size_t voxel_count_ = 0;
  std::span<Range> block_range_;
  std::span<CellKey> sections_;
  std::size_t section_count_ = 0;
  CellIndex block_index_;
  Counters counters_;
};

}  // namespace blockmap::planes
