#include "blockmap/planes/section_grid.hpp"

#include <algorithm>

#include "blockmap/core/check.hpp"

namespace blockmap::planes {
namespace {

std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  const std::int64_t q = a / b;
  return (a % b != 0 && (a < 0) != (b < 0)) ? q - 1 : q;
}

}  // namespace

void SectionGrid::init(Arena& arena, std::size_t max_voxels, std::uint32_t voxels_per_block,
                       std::uint32_t blocks_per_section, double voxel_size_m) {
  BLOCKMAP_CHECK_MSG(voxels_per_block >= 1 && blocks_per_section >= 1, "bad section geometry");
  voxels_per_block_ = voxels_per_block;
  blocks_per_section_ = blocks_per_section;
  block_size_m_ = voxels_per_block * voxel_size_m;
  order_ = arena.allocate_array<BlockVoxel>(max_voxels, "planes.section_grid");
  voxel_order_ = arena.allocate_array<std::uint32_t>(max_voxels, "planes.section_grid");
  block_range_ = arena.allocate_array<Range>(max_voxels, "planes.section_grid");
  // Every block starts k^3 candidate sections before duplicates go.
  sections_ = arena.allocate_array<CellKey>(
      max_voxels * blocks_per_section * blocks_per_section * blocks_per_section,
      "planes.section_grid");
  block_index_.init(arena, max_voxels, "planes.section_grid");
}

CellKey SectionGrid::block_of(CellKey voxel) const noexcept {
  const auto cell = unpack_cell(voxel);
  const auto per = static_cast<std::int64_t>(voxels_per_block_);
  return pack_cell(floor_div(cell.x(), per), floor_div(cell.y(), per), floor_div(cell.z(), per));
}

void SectionGrid::build(const VoxelGrid& grid) noexcept {
  counters_ = Counters{};
  const std::span<const Voxel> slots = grid.slots();
  const std::span<const std::uint32_t> ids = grid.occupied();
  const std::size_t n = std::min(ids.size(), order_.size());
  for (std::size_t i = 0; i < n; ++i) {
    order_[i] = BlockVoxel{block_of(slots[ids[i]].key), ids[i]};
  }
  std::sort(order_.begin(), order_.begin() + static_cast<std::ptrdiff_t>(n),
            [](const BlockVoxel& a, const BlockVoxel& b) {
              return a.block != b.block ? a.block < b.block : a.voxel < b.voxel;
            });
  for (std::size_t i = 0; i < n; ++i) {
    voxel_order_[i] = order_[i].voxel;
  }
  voxel_count_ = n;
  // One range per occupied block.
  block_index_.clear();
  std::size_t blocks = 0;
  for (std::size_t i = 0; i < n;) {
    std::size_t end = i;
    while (end < n && order_[end].block == order_[i].block) {
      ++end;
    }
    std::uint32_t slot = 0;
    block_index_.find_or_insert(order_[i].block, static_cast<std::uint32_t>(blocks), slot);
    block_range_[blocks++] = Range{static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(end)};
    i = end;
  }
  // A section starting at block s covers blocks s .. s + k - 1: every occupied block b is in
  // the sections starting at b - k + 1 .. b.
  section_count_ = 0;
  const auto k = static_cast<std::int64_t>(blocks_per_section_);
  for (std::size_t i = 0; i < n;) {
    const CellKey block = order_[i].block;
    while (i < n && order_[i].block == block) {
      ++i;
    }
    const auto b = unpack_cell(block);
    for (std::int64_t dx = 0; dx < k; ++dx) {
      for (std::int64_t dy = 0; dy < k; ++dy) {
        for (std::int64_t dz = 0; dz < k; ++dz) {
          if (section_count_ == sections_.size()) {
            ++counters_.sections_dropped_full;
            continue;
          }
          sections_[section_count_++] = pack_cell(b.x() - dx, b.y() - dy, b.z() - dz);
        }
      }
    }
  }
  std::sort(sections_.begin(), sections_.begin() + static_cast<std::ptrdiff_t>(section_count_));
  section_count_ = static_cast<std::size_t>(
      std::unique(sections_.begin(),
                  sections_.begin() + static_cast<std::ptrdiff_t>(section_count_)) -
      sections_.begin());
}

std::size_t SectionGrid::gather(CellKey section, std::span<std::uint32_t> out) noexcept {
  const auto s = unpack_cell(section);
  const auto k = static_cast<std::int64_t>(blocks_per_section_);
  std::size_t count = 0;
  for (std::int64_t dx = 0; dx < k; ++dx) {
    for (std::int64_t dy = 0; dy < k; ++dy) {
      for (std::int64_t dz = 0; dz < k; ++dz) {
        const std::uint32_t block =
            block_index_.find(pack_cell(s.x() + dx, s.y() + dy, s.z() + dz));
        if (block == CellIndex::kAbsent) {
          continue;
        }
        const Range range = block_range_[block];
        for (std::uint32_t i = range.begin; i < range.end; ++i) {
          if (count == out.size()) {
            ++counters_.voxels_dropped_full;
            continue;
          }
          out[count++] = order_[i].voxel;
        }
      }
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
