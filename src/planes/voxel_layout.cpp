// VoxelGrid::compact(): the samples laid out block by block, blocks in Z-order; with kept
// shapes, only the blocks that changed are read from the table again.
#include <algorithm>
#include <bit>
#include <cstdint>

#include "blockmap/core/merge_in_place.hpp"
#include "blockmap/planes/voxel_grid.hpp"

namespace blockmap::planes {

namespace {

// Spreads the low 21 bits of v to every third bit (the Morton interleave of one axis).
std::uint64_t spread_bits(std::uint64_t v) noexcept {
  v &= 0x1FFFFF;
  v = (v | (v << 32)) & 0x1F00000000FFFFull;
  v = (v | (v << 16)) & 0x1F0000FF0000FFull;
  v = (v | (v << 8)) & 0x100F00F00F00F00Full;
  v = (v | (v << 4)) & 0x10C30C30C30C30C3ull;
  v = (v | (v << 2)) & 0x1249249249249249ull;
  return v;
}

// The Z-order (Morton) code of a packed key: keys near in space are mostly near in this order.
std::uint64_t morton_code(CellKey key) noexcept {
  return (spread_bits(key >> 42) << 2) | (spread_bits(key >> 21) << 1) | spread_bits(key);
}

// A sample's sums moved from its cell's centre to its block's centre (1.5 cells from the
// cell at the block's low corner), once per sample, so that the shape pass adds them as they
// are.
CentredSums about_block_centre(const VoxelSums& sums, std::uint32_t bit, float size_m) noexcept {
  CentredSums cell;
  cell.values[0] = static_cast<float>(sums.point_count);
  std::copy_n(sums.sum_m, 3, cell.values.begin() + 1);
  std::copy_n(sums.sum_outer_m2, 6, cell.values.begin() + 4);
  return cell.moved_by({(static_cast<float>(bit >> 4) - 1.5f) * size_m,
                        (static_cast<float>((bit >> 2) & 3) - 1.5f) * size_m,
                        (static_cast<float>(bit & 3) - 1.5f) * size_m});
}

}  // namespace

void VoxelGrid::compact() noexcept {
  // Kept shapes come with a flag per block that says whether it changed: then only those
  // need reading, and the order of the others is still sorted.
  const bool incremental = keeping_shapes_ && ordered_blocks_ > 0;
  order_blocks(incremental);
  if (incremental) {
    lay_out_changed_blocks();
  } else {
    lay_out_all_blocks();
  }
  forget_block_sums();
  ordered_blocks_ = block_count_;
  for (std::size_t i = 0; keeping_shapes_ && i < block_count_; ++i) {
    block_order_[i].first = block_first_[block_order_[i].block];
    block_flags_[block_order_[i].block] |= kPlaced;
  }
}

void VoxelGrid::forget_block_sums() noexcept {
  if (!keeping_shapes_) {
    std::fill_n(block_summed_.begin(), block_count_, std::uint8_t{0});  // summed when needed
    return;
  }
  // A block's sums are its samples' centred sums added in bit order: the same until one of
  // them changes (a block read from the table again holds the same sums, summed alike, but it
  // is summed again all the same). A new block, or an index that serves a new key, changed.
  for (std::size_t block = 0; block < block_count_; ++block) {
    if ((block_flags_[block] & (kChanged | kLoaded)) != 0) {
      block_summed_[block] = 0;
    }
  }
}

void VoxelGrid::order_blocks(bool keep_placed) noexcept {
  // Blocks in Z-order: a sample's neighbours in the 26 blocks around its own are then mostly
  // near it in memory too (in first-touch order they were anywhere along the path).
  const auto by_code = [](const BlockOrder& a, const BlockOrder& b) { return a.code < b.code; };
  const auto placed = [this](std::size_t block) { return (block_flags_[block] & kPlaced) != 0; };
  if (keep_placed) {
    // The fresh ones are merged in from the back (below) while they wait at the far end of
    // the array, which needs kept + 2 x fresh entries of room (merge_back_into_front). Without
    // it every block is sorted afresh and laid out from the table; that happens only with the
    // order nearly full (VoxelGrid.ABlockOrderNearlyFullLaysOutAsAGridBuiltAfresh).
    std::size_t kept = 0;
    for (std::size_t i = 0; i < ordered_blocks_; ++i) {
      kept += placed(block_order_[i].block) ? 1U : 0U;
    }
    std::size_t fresh = 0;
    for (std::size_t block = 0; block < block_count_; ++block) {
      fresh += placed(block) ? 0U : 1U;
    }
    keep_placed = kept + 2 * fresh <= block_order_.size();
  }
  if (!keep_placed) {
    for (std::size_t block = 0; block < block_count_; ++block) {
      block_order_[block] = BlockOrder{morton_code(block_keys_[block]),
                                       static_cast<std::uint32_t>(block), kNotLaidOut};
    }
    std::sort(block_order_.begin(),
              block_order_.begin() + static_cast<std::ptrdiff_t>(block_count_), by_code);
    return;
  }
  // The blocks still placed keep their order (an index that serves a new key is not placed);
  // the others are sorted at the far end of the array and merged in from the back.
  std::size_t kept = 0;
  for (std::size_t i = 0; i < ordered_blocks_; ++i) {
    if (placed(block_order_[i].block)) {
      block_order_[kept++] = block_order_[i];
    }
  }
  const std::size_t end = block_order_.size();
  std::size_t fresh = 0;
  for (std::size_t block = 0; block < block_count_; ++block) {
    if (!placed(block)) {
      block_order_[end - ++fresh] = BlockOrder{morton_code(block_keys_[block]),
                                               static_cast<std::uint32_t>(block), kNotLaidOut};
    }
  }
  const auto fresh_first = block_order_.begin() + static_cast<std::ptrdiff_t>(end - fresh);
  std::sort(fresh_first, block_order_.end(), by_code);
  merge_back_into_front(block_order_, kept, fresh, by_code);
}

std::uint32_t VoxelGrid::slot_of_cell(std::uint32_t block, std::uint32_t bit) const noexcept {
  const Eigen::Matrix<std::int64_t, 3, 1> base = unpack_cell(block_keys_[block]) * kBlockEdge;
  // A cell marked in its block always has its slot: blocks are marked on creation.
  return find(pack_cell(base.x() + (bit >> 4), base.y() + ((bit >> 2) & 3), base.z() + (bit & 3)));
}

std::uint64_t VoxelGrid::live_cells(std::uint32_t block) const noexcept {
  std::uint64_t live = 0;
  for (std::uint64_t cells = block_masks_[block]; cells != 0; cells &= cells - 1) {
    const auto bit = static_cast<std::uint32_t>(std::countr_zero(cells));
    if (table_[slot_of_cell(block, bit)].point_count > 0) {  // else every point was taken out
      live |= std::uint64_t{1} << bit;
    }
  }
  return live;
}

std::uint64_t VoxelGrid::load_block(std::uint32_t block, std::uint64_t cells,
                                    std::size_t first) noexcept {
  std::uint64_t live = 0;
  std::size_t id = first;
  if (keeping_shapes_) {
    block_flags_[block] |= kLoaded;
  }
  for (; cells != 0; cells &= cells - 1) {
    const auto bit = static_cast<std::uint32_t>(std::countr_zero(cells));
    const std::uint32_t slot = slot_of_cell(block, bit);
    const VoxelSums& sums = table_[slot];
    if (sums.point_count == 0) {
      continue;  // every point taken back out
    }
    if (keeping_shapes_) {
      dense_serial_[id] = serial_of_slot_[slot];
    }
    centred_sums_[id] = about_block_centre(sums, bit, size_m_);
    Voxel& voxel = voxels_[id++];
    voxel = Voxel{};
    static_cast<VoxelSums&>(voxel) = sums;
    voxel.block = block;
    live |= std::uint64_t{1} << bit;
  }
  return live;
}

void VoxelGrid::prefetch_block_cells(std::uint32_t block) const noexcept {
  // A block's cells hash to the slots after the home slot of its first cell (offset by their
  // bit); the table is tens of MiB, so a walk over blocks fetches the slots of a block a few
  // places on while it reads this one's.
  const Eigen::Matrix<std::int64_t, 3, 1> base = unpack_cell(block_keys_[block]) * kBlockEdge;
  const std::size_t home = home_slot(pack_cell(base.x(), base.y(), base.z()));
  // Written out, not as a loop: GCC deletes a loop whose only effect is a prefetch. Most
  // blocks hold fewer than six samples.
  std::uint64_t cells = block_masks_[block];
  const auto fetch_lowest_cell = [&] {
    if (cells != 0) {
      __builtin_prefetch(
          &table_[(home + static_cast<std::size_t>(std::countr_zero(cells))) & mask_]);
      cells &= cells - 1;
    }
  };
  fetch_lowest_cell();
  fetch_lowest_cell();
  fetch_lowest_cell();
  fetch_lowest_cell();
  fetch_lowest_cell();
  fetch_lowest_cell();
}

void VoxelGrid::lay_out_all_blocks() noexcept {
  count_ = 0;
  for (std::size_t i = 0; i < std::min(kPrefetchAheadBlocks, block_count_); ++i) {
    prefetch_block_cells(block_order_[i].block);
  }
  for (std::size_t i = 0; i < block_count_; ++i) {
    if (i + kPrefetchAheadBlocks < block_count_) {
      prefetch_block_cells(block_order_[i + kPrefetchAheadBlocks].block);
    }
    const std::uint32_t block = block_order_[i].block;
    block_first_[block] = static_cast<std::uint32_t>(count_);
    live_masks_[block] = load_block(block, block_masks_[block], count_);
    count_ += static_cast<std::size_t>(std::popcount(live_masks_[block]));
  }
}

void VoxelGrid::move_samples(std::size_t from, std::size_t to, std::size_t count) noexcept {
  const auto move = [&](auto span) {
    const auto source = span.begin() + static_cast<std::ptrdiff_t>(from);
    const auto target = span.begin() + static_cast<std::ptrdiff_t>(to);
    const auto source_end = source + static_cast<std::ptrdiff_t>(count);
    if (to < from) {
      std::copy(source, source_end, target);
    } else {
      std::copy_backward(source, source_end, target + static_cast<std::ptrdiff_t>(count));
    }
  };
  move(voxels_);
  move(centred_sums_);
  move(dense_serial_);
}

void VoxelGrid::lay_out_changed_blocks() noexcept {
  place_blocks_keeping_order();
  move_kept_blocks();
  load_changed_blocks();
}

bool VoxelGrid::reloaded(const BlockOrder& entry) const noexcept {
  return entry.first == kNotLaidOut || (block_flags_[entry.block] & kChanged) != 0;
}

void VoxelGrid::prefetch_if_reloaded(std::size_t i) const noexcept {
  if (i < block_count_ && reloaded(block_order_[i])) {
    prefetch_block_cells(block_order_[i].block);
  }
}

void VoxelGrid::prefetch_reloaded_ahead_of(std::size_t i) const noexcept {
  if (i == 0) {
    for (std::size_t k = 0; k < kPrefetchAheadBlocks; ++k) {
      prefetch_if_reloaded(k);
    }
  }
  prefetch_if_reloaded(i + kPrefetchAheadBlocks);
}

void VoxelGrid::place_blocks_keeping_order() noexcept {
  // A changed block's live cells are read from the table, a kept one's are as they were.
  // block_first_ takes the new place, the entry keeps the old.
  count_ = 0;
  for (std::size_t i = 0; i < block_count_; ++i) {
    prefetch_reloaded_ahead_of(i);
    const BlockOrder& entry = block_order_[i];
    if (reloaded(entry)) {
      live_masks_[entry.block] = live_cells(entry.block);
    }
    block_first_[entry.block] = static_cast<std::uint32_t>(count_);
    count_ += static_cast<std::size_t>(std::popcount(live_masks_[entry.block]));
  }
}

void VoxelGrid::move_kept_blocks() noexcept {
  // Kept blocks move in runs (neighbours in the layout with the same shift): the ones that
  // move towards the front in order, then the ones that move back in reverse order. The
  // order is the same before and after, so neither overwrites samples still to move.
  struct Run {
    std::size_t from = 0;
    std::size_t to = 0;
    std::size_t count = 0;
  };
  Run run;
  const auto flush = [&] {
    if (run.count > 0) {
      move_samples(run.from, run.to, run.count);
    }
    run = Run{};
  };
  for (std::size_t i = 0; i < block_count_; ++i) {
    const BlockOrder& entry = block_order_[i];
    const std::size_t to = block_first_[entry.block];
    if (reloaded(entry) || to >= entry.first) {
      continue;
    }
    const auto count = static_cast<std::size_t>(std::popcount(live_masks_[entry.block]));
    if (run.count == 0 || entry.first != run.from + run.count || to != run.to + run.count) {
      flush();
      run = Run{entry.first, to, 0};
    }
    run.count += count;
  }
  flush();
  for (std::size_t i = block_count_; i-- > 0;) {
    const BlockOrder& entry = block_order_[i];
    const std::size_t to = block_first_[entry.block];
    if (reloaded(entry) || to <= entry.first) {
      continue;
    }
    const auto count = static_cast<std::size_t>(std::popcount(live_masks_[entry.block]));
    if (run.count == 0 || entry.first + count != run.from || to + count != run.to) {
      flush();
      run = Run{entry.first + count, to + count, 0};
    }
    run.from -= count;
    run.to -= count;
    run.count += count;
  }
  flush();
}

void VoxelGrid::load_changed_blocks() noexcept {
  for (std::size_t i = 0; i < block_count_; ++i) {
    prefetch_reloaded_ahead_of(i);
    const BlockOrder& entry = block_order_[i];
    if (reloaded(entry)) {
      load_block(entry.block, live_masks_[entry.block], block_first_[entry.block]);
    }
  }
}

}  // namespace blockmap::planes
