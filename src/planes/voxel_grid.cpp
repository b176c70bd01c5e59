#include "blockmap/planes/voxel_grid.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <iterator>
#include <numbers>

#include <Eigen/Geometry>

#include "blockmap/core/check.hpp"
#include "blockmap/core/linear_probing.hpp"
#include "blockmap/core/merge_in_place.hpp"
#include "blockmap/planes/fast_trig.hpp"

namespace blockmap::planes {

// ---- CellIndex ----

void CellIndex::init(Arena& arena, std::size_t max_keys, const char* owner) {
  BLOCKMAP_CHECK_MSG(max_keys > 0, "cell index needs a capacity");
  // At most half full: short probe sequences.
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(2 * max_keys, 64));
  shift_ = 64u - static_cast<std::uint32_t>(std::countr_zero(slots));
  mask_ = slots - 1;
  slots_ = arena.allocate_array<Slot>(slots, owner);
  max_keys_ = max_keys;
  clear();
}

void CellIndex::clear() noexcept {
  std::fill(slots_.begin(), slots_.end(), Slot{});
  size_ = 0;
}

std::uint32_t CellIndex::find(CellKey key) const noexcept {
  for (std::size_t slot = home_slot(key);; slot = (slot + 1) & mask_) {
    const Slot& s = slots_[slot];
    if (s.value == kAbsent) {
      return kAbsent;
    }
    if (s.key == key) {
      return s.value;
    }
  }
}

bool CellIndex::find_or_insert(CellKey key, std::uint32_t value, std::uint32_t& found) noexcept {
  for (std::size_t slot = home_slot(key);; slot = (slot + 1) & mask_) {
    Slot& s = slots_[slot];
    if (s.value == kAbsent) {
      if (size_ == max_keys_) {
        return false;
      }
      s = Slot{key, value};
      ++size_;
      found = value;
      return true;
    }
    if (s.key == key) {
      found = s.value;
      return true;
    }
  }
}

void CellIndex::erase(CellKey key) noexcept {
  std::size_t slot = home_slot(key);
  for (; slots_[slot].key != key; slot = (slot + 1) & mask_) {
    if (slots_[slot].value == kAbsent) {
      return;
    }
  }
  if (slots_[slot].value == kAbsent) {
    return;  // an empty slot that holds the key's bits by chance
  }
  erase_shifting_back(
      slot, mask_, [this](std::size_t at) { return slots_[at].value != kAbsent; },
      [this](std::size_t at) { return home_slot(slots_[at].key); },
      [this](std::size_t from, std::size_t to) { slots_[to] = slots_[from]; },
      [this](std::size_t at) { slots_[at] = Slot{}; });
  --size_;
}

std::size_t CellIndex::arena_bytes(std::size_t max_keys) noexcept {
  return std::bit_ceil(std::max<std::size_t>(2 * max_keys, 64)) * sizeof(Slot) + 64;
}

// ---- VoxelGrid ----

void VoxelGrid::init(Arena& arena, double voxel_size_m, std::size_t max_voxels,
                     std::size_t max_blocks) {
  BLOCKMAP_CHECK_MSG(voxel_size_m > 0.0 && max_voxels > 0, "voxel size and capacity must be > 0");
  voxel_size_m_ = voxel_size_m;
  inverse_size_ = static_cast<float>(1.0 / voxel_size_m);
  size_m_ = static_cast<float>(voxel_size_m);
  // At most half full: short probe sequences.
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(2 * max_voxels, 64));
  shift_ = 64u - static_cast<std::uint32_t>(std::countr_zero(slots));
  mask_ = slots - 1;
  table_ = arena.allocate_array<VoxelSums>(slots, "planes.voxel_grid");
  voxels_ = arena.allocate_array<Voxel>(max_voxels, "planes.voxel_grid");
  // At most one block per voxel.
  const std::size_t blocks = max_blocks == 0 ? max_voxels : std::min(max_blocks, max_voxels);
  block_index_.init(arena, blocks, "planes.voxel_grid");
  block_keys_ = arena.allocate_array<CellKey>(blocks, "planes.voxel_grid");
  block_masks_ = arena.allocate_array<std::uint64_t>(blocks, "planes.voxel_grid");
  live_masks_ = arena.allocate_array<std::uint64_t>(blocks, "planes.voxel_grid");
  block_first_ = arena.allocate_array<std::uint32_t>(blocks, "planes.voxel_grid");
  block_order_ = arena.allocate_array<BlockOrder>(blocks, "planes.voxel_grid");
  centred_sums_ = arena.allocate_array<CentredSums>(max_voxels, "planes.voxel_grid");
  block_sums_ = arena.allocate_array<CentredSums>(blocks, "planes.voxel_grid");
  block_summed_ = arena.allocate_array<std::uint8_t>(blocks, "planes.voxel_grid");
  free_blocks_ = arena.allocate_array<std::uint32_t>(blocks, "planes.voxel_grid");
  slot_count_ = 0;
  clear();
}

void VoxelGrid::keep_shapes(Arena& arena) {
  const std::size_t max_voxels = voxels_.size();
  serial_of_slot_ = arena.allocate_array<std::uint32_t>(table_.size(), "planes.kept_shapes");
  free_serials_ = arena.allocate_array<std::uint32_t>(max_voxels, "planes.kept_shapes");
  dense_serial_ = arena.allocate_array<std::uint32_t>(max_voxels, "planes.kept_shapes");
  kept_ = arena.allocate_array<KeptShape>(max_voxels, "planes.kept_shapes");
  block_flags_ = arena.allocate_array<std::uint8_t>(block_keys_.size(), "planes.kept_shapes");
  changed_cells_ = arena.allocate_array<std::uint64_t>(block_keys_.size(), "planes.kept_shapes");
  kept_coarse_ = arena.allocate_array<CoarseSpread>(block_keys_.size(), "planes.kept_shapes");
  keeping_shapes_ = true;
  clear();
}

std::size_t VoxelGrid::shape_cache_bytes(std::size_t max_voxels, std::size_t max_blocks) noexcept {
  const std::size_t blocks = max_blocks == 0 ? max_voxels : max_blocks;
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(2 * max_voxels, 64));
  constexpr std::size_t kAlignment = 64;  // per allocation, at most
  return slots * sizeof(std::uint32_t) +
         max_voxels * (2 * sizeof(std::uint32_t) + sizeof(KeptShape)) +
         blocks * (sizeof(std::uint8_t) + sizeof(std::uint64_t) + sizeof(CoarseSpread)) +
         7 * kAlignment;
}

std::size_t VoxelGrid::arena_bytes(std::size_t max_voxels, std::size_t max_blocks) noexcept {
  const std::size_t blocks = max_blocks == 0 ? max_voxels : max_blocks;
  const std::size_t slots = std::bit_ceil(std::max<std::size_t>(2 * max_voxels, 64));
  constexpr std::size_t kAlignment = 64;  // per allocation, at most
  return slots * sizeof(VoxelSums) + max_voxels * (sizeof(Voxel) + sizeof(CentredSums)) +
         blocks * (sizeof(CellKey) + 2 * sizeof(std::uint64_t) + 2 * sizeof(std::uint32_t) +
                   sizeof(BlockOrder) + sizeof(CentredSums) + sizeof(std::uint8_t)) +
         CellIndex::arena_bytes(blocks) + 11 * kAlignment;
}

std::size_t VoxelGrid::count_voxels(std::span<const Eigen::Vector3f> points_m, double voxel_size_m,
                                    std::span<CellKey> scratch) noexcept {
  BLOCKMAP_CHECK_MSG(scratch.size() >= points_m.size(), "count_voxels needs a key per point");
  // The grid's own arithmetic: a point on a cell border falls where add_points puts it.
  const auto inverse = static_cast<float>(1.0 / voxel_size_m);
  std::size_t keys = 0;
  for (const Eigen::Vector3f& p : points_m) {
    const LocatedPoint located = locate(p, inverse);
    if (located.status == LocatedPoint::Status::kOk) {
      scratch[keys++] = located.key;
    }
  }
  const auto first = scratch.begin();
  const auto last = first + static_cast<std::ptrdiff_t>(keys);
  std::sort(first, last);
  return static_cast<std::size_t>(std::unique(first, last) - first);
}

void VoxelGrid::clear() noexcept {
  // Block indices start over: no block's coarse spread is known.
  for (std::size_t block = 0; keeping_shapes_ && block < block_count_; ++block) {
    kept_coarse_[block].known = false;
  }
  for (VoxelSums& slot : table_) {
    slot.key = kNoCell;
  }
  slot_count_ = 0;
  free_serial_count_ = 0;
  next_serial_ = 0;
  count_ = 0;
  block_index_.clear();
  block_count_ = 0;
  ordered_blocks_ = 0;
  free_block_count_ = 0;
  last_index_ = CellIndex::kAbsent;
  counters_ = Counters{};
}

std::uint32_t VoxelGrid::find(CellKey key) const noexcept {
  for (std::size_t slot = home_slot(key);; slot = (slot + 1) & mask_) {
    const CellKey k = table_[slot].key;
    if (k == key) {
      return static_cast<std::uint32_t>(slot);
    }
    if (k == kNoCell) {
      return CellIndex::kAbsent;
    }
  }
}

std::uint32_t VoxelGrid::find_or_create(CellKey key) noexcept {
  for (std::size_t slot = home_slot(key);; slot = (slot + 1) & mask_) {
    VoxelSums& voxel = table_[slot];
    if (voxel.key == key) {
      return static_cast<std::uint32_t>(slot);
    }
    if (voxel.key == kNoCell) {
      const auto cell = unpack_cell(key);
      if (slot_count_ == voxels_.size() || !mark_in_block(cell.x(), cell.y(), cell.z())) {
        return CellIndex::kAbsent;
      }
      voxel = VoxelSums{.key = key};
      if (keeping_shapes_) {
        const std::uint32_t serial =
            free_serial_count_ > 0 ? free_serials_[--free_serial_count_] : next_serial_++;
        serial_of_slot_[slot] = serial;
        kept_[serial].valid = false;
      }
      ++slot_count_;
      return static_cast<std::uint32_t>(slot);
    }
  }
}

bool VoxelGrid::mark_in_block(std::int64_t x, std::int64_t y, std::int64_t z) noexcept {
  std::uint32_t block = 0;
  const CellKey key = block_of_cell(x, y, z);
  const bool reuse = free_block_count_ > 0;
  const auto fresh =
      reuse ? free_blocks_[free_block_count_ - 1] : static_cast<std::uint32_t>(block_count_);
  if (!reuse && block_count_ == block_keys_.size()) {
    // Full: only a block that exists already can take the cell.
    block = block_index_.find(key);
    if (block == CellIndex::kAbsent) {
      return false;
    }
  } else if (block_index_.find_or_insert(key, fresh, block) && block == fresh) {
    if (reuse) {
      --free_block_count_;
    } else {
      ++block_count_;
    }
    block_keys_[block] = key;
    block_masks_[block] = 0;
    live_masks_[block] = 0;
    block_first_[block] = 0;
    if (keeping_shapes_) {
      kept_coarse_[block].known = false;
      block_flags_[block] = kChanged;  // all new, and not placed under this key
      changed_cells_[block] = 0;
    }
  }
  block_masks_[block] |= std::uint64_t{1} << bit_in_block(x, y, z);
  if (keeping_shapes_) {
    mark_cell_changed(block, bit_in_block(x, y, z));  // a new cell
  }
  return true;
}

void VoxelGrid::unmark_in_block(CellKey key) noexcept {
  const auto cell = unpack_cell(key);
  const CellKey block_key = block_of_cell(cell.x(), cell.y(), cell.z());
  const std::uint32_t block = block_index_.find(block_key);
  if (block == CellIndex::kAbsent) {
    return;
  }
  block_masks_[block] &= ~(std::uint64_t{1} << bit_in_block(cell.x(), cell.y(), cell.z()));
  if (keeping_shapes_) {
    mark_cell_changed(block, bit_in_block(cell.x(), cell.y(), cell.z()));  // its neighbours'
  }
  if (block_masks_[block] != 0) {
    return;
  }
  // Empty: its index serves the next new block. The blocks around it are stale now, while
  // its key still says where it was.
  if (keeping_shapes_) {
    mark_stale_around(block_key, kStale | kAllStale);
  }
  block_index_.erase(block_key);
  free_blocks_[free_block_count_++] = block;
}

void VoxelGrid::mark_changed(CellKey key) noexcept {
  const auto cell = unpack_cell(key);
  const std::uint32_t block = block_index_.find(block_of_cell(cell.x(), cell.y(), cell.z()));
  if (block != CellIndex::kAbsent) {
    mark_cell_changed(block, bit_in_block(cell.x(), cell.y(), cell.z()));
  }
}

void VoxelGrid::mark_cell_changed(std::uint32_t block, std::uint32_t bit) noexcept {
  block_flags_[block] |= kChanged;
  changed_cells_[block] |= std::uint64_t{1} << bit;
}

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
  constexpr std::size_t kAhead = 16;
  for (std::size_t i = 0; i < std::min(kAhead, block_count_); ++i) {
    prefetch_block_cells(block_order_[i].block);
  }
  for (std::size_t i = 0; i < block_count_; ++i) {
    if (i + kAhead < block_count_) {
      prefetch_block_cells(block_order_[i + kAhead].block);
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
  const auto reloaded = [this](const BlockOrder& entry) {
    return entry.first == kNotLaidOut || (block_flags_[entry.block] & kChanged) != 0;
  };
  // The table slots of the changed blocks a few places on are fetched while these are read.
  constexpr std::size_t kAhead = 16;
  const auto prefetch_reloaded = [&](std::size_t i) {
    if (i < block_count_ && reloaded(block_order_[i])) {
      prefetch_block_cells(block_order_[i].block);
    }
  };
  // Where each block's samples go: a changed block's live cells are read from the table, a
  // kept one's are as they were. block_first_ takes the new place, the entry keeps the old.
  count_ = 0;
  for (std::size_t i = 0; i < kAhead; ++i) {
    prefetch_reloaded(i);
  }
  for (std::size_t i = 0; i < block_count_; ++i) {
    prefetch_reloaded(i + kAhead);
    const BlockOrder& entry = block_order_[i];
    if (reloaded(entry)) {
      live_masks_[entry.block] = live_cells(entry.block);
    }
    block_first_[entry.block] = static_cast<std::uint32_t>(count_);
    count_ += static_cast<std::size_t>(std::popcount(live_masks_[entry.block]));
  }
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
  for (std::size_t i = 0; i < kAhead; ++i) {
    prefetch_reloaded(i);
  }
  for (std::size_t i = 0; i < block_count_; ++i) {
    prefetch_reloaded(i + kAhead);
    const BlockOrder& entry = block_order_[i];
    if (reloaded(entry)) {
      load_block(entry.block, live_masks_[entry.block], block_first_[entry.block]);
    }
  }
}

CentredSums VoxelGrid::sum_block(std::uint32_t block) const noexcept {
  CentredSums sums;
  const BlockRange range = block_range(block);
  for (std::uint32_t id = range.first; id < range.first + range.count; ++id) {
    sums.add(centred_sums_[id]);
  }
  return sums;
}

VoxelGrid::BlockRange VoxelGrid::block_range(std::size_t block) const noexcept {
  return {block_first_[block], static_cast<std::uint32_t>(std::popcount(live_masks_[block]))};
}

Eigen::Vector3f VoxelGrid::centre_m(CellKey key) const noexcept {
  const auto cell = unpack_cell(key);
  return ((cell.cast<double>().array() + 0.5) * voxel_size_m_).matrix().cast<float>();
}

Eigen::Vector3f VoxelGrid::centroid_m(const VoxelSums& voxel) const noexcept {
  const float n = static_cast<float>(std::max<std::uint32_t>(voxel.point_count, 1));
  return centre_m(voxel.key) + Eigen::Vector3f(voxel.sum_m[0], voxel.sum_m[1], voxel.sum_m[2]) / n;
}

PointMoments VoxelGrid::moments_of(const VoxelSums& voxel, double voxel_size_m,
                                   const Eigen::Vector3d& origin_m) noexcept {
  PointMoments local;
  local.weight = voxel.point_count;
  local.sum = Eigen::Vector3f(voxel.sum_m[0], voxel.sum_m[1], voxel.sum_m[2]).cast<double>();
  const float* s = voxel.sum_outer_m2;
  Eigen::Matrix3f outer;
  outer << s[0], s[1], s[2], s[1], s[3], s[4], s[2], s[4], s[5];
  local.sum_outer = outer.cast<double>();
  const Eigen::Vector3d centre =
      ((unpack_cell(voxel.key).cast<double>().array() + 0.5) * voxel_size_m).matrix();
  return local.shifted(centre.cast<float>().cast<double>() - origin_m);
}

inline VoxelGrid::LocatedPoint VoxelGrid::locate(const Eigen::Vector3f& point_m,
                                                 float inverse_size) noexcept {
  LocatedPoint located;
  if (!point_m.allFinite()) {
    located.status = LocatedPoint::Status::kNonFinite;
    return located;
  }
  const Eigen::Vector3f scaled = point_m * inverse_size;
  // Far beyond the key range is checked in float first: a huge float does not fit an int64.
  constexpr auto kFarCells = static_cast<float>(2 * kCellKeyBias);
  const Eigen::Vector3f floored = scaled.array().floor();
  if (floored.cwiseAbs().maxCoeff() >= kFarCells) {
    located.status = LocatedPoint::Status::kOutOfRange;
    return located;
  }
  const auto x = static_cast<std::int64_t>(floored.x());
  const auto y = static_cast<std::int64_t>(floored.y());
  const auto z = static_cast<std::int64_t>(floored.z());
  if (!cell_in_range(x, y, z)) {
    located.status = LocatedPoint::Status::kOutOfRange;
    return located;
  }
  located.key = pack_cell(x, y, z);
  // The offset from the voxel's centre, from the fraction of the scaled point.
  located.offset = (scaled - floored).array() - 0.5f;
  return located;
}

inline void VoxelGrid::accumulate(const LocatedPoint& point, int sign) noexcept {
  switch (point.status) {
    case LocatedPoint::Status::kNonFinite:
      ++counters_.points_dropped_nonfinite;
      return;
    case LocatedPoint::Status::kOutOfRange:
      ++counters_.points_dropped_range;
      return;
    case LocatedPoint::Status::kOk:
      break;
  }
  // Consecutive points of a scan often fall in the same voxel: remember the last one.
  if (point.key != last_key_ || last_index_ == CellIndex::kAbsent) {
    const std::uint32_t id = find_or_create(point.key);
    if (id == CellIndex::kAbsent) {
      ++counters_.points_dropped_full;
      return;
    }
    last_key_ = point.key;
    last_index_ = id;
  }
  VoxelSums& voxel = table_[last_index_];
  const Eigen::Vector3f& local = point.offset;
  const float s = static_cast<float>(sign) * size_m_;
  const float s2 = s * size_m_;
  voxel.point_count =
      static_cast<std::uint32_t>(static_cast<std::int64_t>(voxel.point_count) + sign);
  voxel.sum_m[0] += s * local.x();
  voxel.sum_m[1] += s * local.y();
  voxel.sum_m[2] += s * local.z();
  voxel.sum_outer_m2[0] += s2 * local.x() * local.x();
  voxel.sum_outer_m2[1] += s2 * local.x() * local.y();
  voxel.sum_outer_m2[2] += s2 * local.x() * local.z();
  voxel.sum_outer_m2[3] += s2 * local.y() * local.y();
  voxel.sum_outer_m2[4] += s2 * local.y() * local.z();
  voxel.sum_outer_m2[5] += s2 * local.z() * local.z();
  if (sign > 0) {
    ++counters_.points_added;
  }
}

void VoxelGrid::add_point(const Eigen::Vector3f& point_m) noexcept {
  BLOCKMAP_CHECK_MSG(!keeping_shapes_, "kept shapes need add_sums or set_sums");
  accumulate(locate(point_m, inverse_size_), 1);
}

std::uint32_t VoxelGrid::slot_for(const VoxelSums& sums) noexcept {
  const Eigen::Matrix<std::int64_t, 3, 1> cell = unpack_cell(sums.key);
  if (!cell_in_range(cell.x(), cell.y(), cell.z())) {
    counters_.points_dropped_range += sums.point_count;
    return CellIndex::kAbsent;
  }
  const std::uint32_t id = find_or_create(sums.key);
  if (id == CellIndex::kAbsent) {
    counters_.points_dropped_full += sums.point_count;
  }
  last_index_ = CellIndex::kAbsent;
  return id;
}

void VoxelGrid::sums_changed(CellKey key) noexcept {
  if (keeping_shapes_) {
    mark_changed(key);
  }
}

void VoxelGrid::add_sums(const VoxelSums& sums) noexcept {
  if (sums.point_count == 0) {
    return;
  }
  const std::uint32_t id = slot_for(sums);
  if (id == CellIndex::kAbsent) {
    return;
  }
  VoxelSums& voxel = table_[id];
  voxel.point_count += sums.point_count;
  for (std::size_t i = 0; i < 3; ++i) {
    voxel.sum_m[i] += sums.sum_m[i];
  }
  for (std::size_t i = 0; i < 6; ++i) {
    voxel.sum_outer_m2[i] += sums.sum_outer_m2[i];
  }
  counters_.points_added += sums.point_count;
  sums_changed(sums.key);
}

void VoxelGrid::prefetch(CellKey key) const noexcept {
  __builtin_prefetch(&table_[home_slot(key)]);
}

void VoxelGrid::set_sums(const VoxelSums& sums) noexcept {
  const std::uint32_t id = slot_for(sums);
  if (id == CellIndex::kAbsent) {
    return;
  }
  VoxelSums& voxel = table_[id];
  const bool same =
      voxel.point_count == sums.point_count &&
      std::equal(std::begin(sums.sum_m), std::end(sums.sum_m), voxel.sum_m) &&
      std::equal(std::begin(sums.sum_outer_m2), std::end(sums.sum_outer_m2), voxel.sum_outer_m2);
  if (same) {
    return;  // nothing changed: its block's shapes stand
  }
  // The points it gained (the window only adds until a tile leaves, and then the mapper
  // starts the grid over).
  counters_.points_added += sums.point_count - std::min(sums.point_count, voxel.point_count);
  voxel = sums;
  sums_changed(sums.key);
}

void VoxelGrid::erase(CellKey key) noexcept {
  const std::uint32_t slot = find(key);
  if (slot == CellIndex::kAbsent) {
    return;
  }
  counters_.points_erased += table_[slot].point_count;
  if (keeping_shapes_) {
    free_serials_[free_serial_count_++] = serial_of_slot_[slot];
  }
  erase_shifting_back(
      slot, mask_, [this](std::size_t at) { return table_[at].key != kNoCell; },
      [this](std::size_t at) { return home_slot(table_[at].key); },
      [this](std::size_t from, std::size_t to) {
        table_[to] = table_[from];
        if (keeping_shapes_) {
          serial_of_slot_[to] = serial_of_slot_[from];
        }
      },
      [this](std::size_t at) { table_[at].key = kNoCell; });
  --slot_count_;
  last_index_ = CellIndex::kAbsent;
  unmark_in_block(key);
}

void VoxelGrid::remove_point(const Eigen::Vector3f& point_m) noexcept {
  BLOCKMAP_CHECK_MSG(!keeping_shapes_, "kept shapes need add_sums or set_sums");
  accumulate(locate(point_m, inverse_size_), -1);
}

void VoxelGrid::add_points(std::span<const Eigen::Vector3f> points_m) noexcept {
  BLOCKMAP_CHECK_MSG(!keeping_shapes_, "kept shapes need add_sums or set_sums");
  // In batches: a batch's points are located first, and the slot of each change of cell
  // fetched (the table is tens of MiB; a new cell is a cache miss), then they are summed
  // while the fetches arrive.
  constexpr std::size_t kBatch = 32;
  std::array<LocatedPoint, kBatch> batch;
  CellKey fetched = kNoCell;
  for (std::size_t first = 0; first < points_m.size(); first += kBatch) {
    const std::size_t count = std::min(kBatch, points_m.size() - first);
    for (std::size_t i = 0; i < count; ++i) {
      batch[i] = locate(points_m[first + i], inverse_size_);
    }
    for (std::size_t i = 0; i < count; ++i) {
      if (batch[i].status == LocatedPoint::Status::kOk && batch[i].key != fetched) {
        fetched = batch[i].key;
        __builtin_prefetch(&table_[home_slot(fetched)]);
      }
    }
    for (std::size_t i = 0; i < count; ++i) {
      accumulate(batch[i], 1);
    }
  }
}

namespace {

// The cells of a block next to its neighbour in direction (dx, dy, dz) (each -1, 0 or 1): the
// ones whose 3 x 3 x 3 neighbourhood reaches into that neighbour.
constexpr std::uint64_t cells_facing(int dx, int dy, int dz) noexcept {
  std::uint64_t mask = 0;
  for (int x = 0; x < 4; ++x) {
    for (int y = 0; y < 4; ++y) {
      for (int z = 0; z < 4; ++z) {
        const bool faces = (dx == 0 || x == (dx < 0 ? 0 : 3)) &&
                           (dy == 0 || y == (dy < 0 ? 0 : 3)) && (dz == 0 || z == (dz < 0 ? 0 : 3));
        if (faces) {
          mask |= std::uint64_t{1} << ((x << 4) | (y << 2) | z);
        }
      }
    }
  }
  return mask;
}

// The index of a block's own entry among the 27 of its neighbourhood (offset 0, 0, 0).
constexpr std::size_t kOwnBlock = 13;

constexpr std::array<std::uint64_t, 27> kCellsFacing = [] {
  std::array<std::uint64_t, 27> masks{};
  std::size_t k = 0;
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dz = -1; dz <= 1; ++dz) {
        masks[k++] = cells_facing(dx, dy, dz);
      }
    }
  }
  return masks;
}();

}  // namespace

void VoxelGrid::load_neighbourhood(std::int64_t bx, std::int64_t by, std::int64_t bz,
                                   std::uint64_t live, BlockNeighbourhood& out) const noexcept {
  // Most blocks hold a few samples on one surface: only the neighbours that their cells touch
  // are looked up.
  std::size_t k = 0;
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dz = -1; dz <= 1; ++dz, ++k) {
        out.live_masks[k] = 0;
        out.first[k] = 0;
        out.changed[k] = 0;
        if ((live & kCellsFacing[k]) == 0) {
          continue;
        }
        const std::uint32_t block = block_index_.find(pack_cell(bx + dx, by + dy, bz + dz));
        if (block != CellIndex::kAbsent) {
          out.live_masks[k] = live_masks_[block];
          out.first[k] = block_first_[block];
          out.changed[k] = keeping_shapes_ ? changed_cells_[block] : 0;
          // The shape pass reads these sums a block or two later.
          __builtin_prefetch(&centred_sums_[block_first_[block]]);
        }
      }
    }
  }
}

void VoxelGrid::estimate_shapes(const ShapeOptions& options,
                                std::span<std::uint32_t> voting_points) noexcept {
  BLOCKMAP_CHECK_MSG(voting_points.empty() || voting_points.size() >= block_count_,
                     "voting points need an entry per block");
  const auto squared = [](double ratio) { return static_cast<float>(ratio * ratio); };
  ShapeLimits limits;
  limits.planar_ratio_sq = squared(options.max_planarity_ratio);
  limits.line_ratio_sq = squared(options.max_line_ratio);
  limits.min_points = static_cast<float>(options.min_points);
  limits.level_slices = options.level_slices;
  double thickness_sum_m = 0.0;
  std::uint64_t planar_count = 0;
  shape_tally_ = ShapeTally{};
  // Erased blocks keep their index and hold no samples: no points.
  std::fill_n(voting_points.begin(), voting_points.empty() ? 0 : block_count_, 0U);
  estimate_fine_shapes(limits, options.every_sample_votes, voting_points, thickness_sum_m,
                       planar_count);
  surface_noise_m_ = planar_count > 0 ? thickness_sum_m / static_cast<double>(planar_count) : 0.0;
  shape_tally_.planar = planar_count;
  // Level slices have no second look: at 2.4 m they are flat too, and only the slice.
  if (options.coarse_second_look && !options.level_slices) {
    take_coarse_look(options, limits, voting_points);
  }
  if (keeping_shapes_) {
    // Changed and stale are done with; placed stays until the index serves a new key, and
    // what the samples went through is what samples_changed() tells till the next pass.
    for (std::size_t block = 0; block < block_count_; ++block) {
      const std::uint8_t flags = block_flags_[block];
      const bool samples_changed = (flags & (kChanged | kLoaded | kReshaped)) != 0;
      block_flags_[block] = static_cast<std::uint8_t>((flags & (kPlaced | kCoarseApplied)) |
                                                      (samples_changed ? kSamplesChanged : 0));
      changed_cells_[block] = 0;
    }
  }
}

void VoxelGrid::take_coarse_look(const ShapeOptions& options, ShapeLimits limits,
                                 std::span<std::uint32_t> voting_points) noexcept {
  const auto squared = [](double ratio) { return static_cast<float>(ratio * ratio); };
  // The second look knows how thick this cloud's surfaces are: a slab a few surface-noise
  // thicknesses thick is a blurred wall (pose errors blur every surface alike), where a crisp
  // cloud's slab of that thickness is a hedge or a row of bushes.
  limits.noisy_slab_ratio_sq = squared(options.max_noisy_slab_ratio);
  limits.noisy_slab_thickness_m2 = squared(options.noisy_slab_per_noise * surface_noise_m_);
  for (std::size_t i = 0; i < block_count_; ++i) {
    const std::uint32_t block = block_order_[i].block;
    const BlockRange range = block_range(block);
    const std::span<Voxel> samples = voxels_.subspan(range.first, range.count);
    const auto scattered = [](const Voxel& v) { return v.shape == LocalShape::kScattered; };
    const Eigen::Vector3f normal = (block_summed_[block] & kHoldsScattered) == 0
                                       ? Eigen::Vector3f::Zero()
                                       : coarse_normal(block, limits);
    if (keeping_shapes_) {
      note_coarse_look(block, !normal.isZero());
    }
    if (normal.isZero()) {
      continue;
    }
    for (Voxel& voxel : samples) {
      if (scattered(voxel)) {
        voxel.shape = LocalShape::kPlanar;
        voxel.axis = normal;
        voxel.coarse_look = true;
        --shape_tally_.scattered;
        ++shape_tally_.planar;
        if (!voting_points.empty() && !options.every_sample_votes) {
          voting_points[block] += voxel.point_count;  // planar now: it votes
        }
      }
    }
  }
}

void VoxelGrid::note_coarse_look(std::uint32_t block, bool applied) noexcept {
  // Applied now and not before, or the other way round: the block's scattered samples changed.
  // (When it was applied both times, a moved normal was noted where it was estimated again.)
  const bool before = (block_flags_[block] & kCoarseApplied) != 0;
  if (applied != before) {
    block_flags_[block] |= kReshaped;
  }
  block_flags_[block] = static_cast<std::uint8_t>(
      applied ? (block_flags_[block] | kCoarseApplied) : (block_flags_[block] & ~kCoarseApplied));
}

void VoxelGrid::mark_stale_around(CellKey block_key, std::uint8_t flags) noexcept {
  const auto b = unpack_cell(block_key);
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dz = -1; dz <= 1; ++dz) {
        const std::uint32_t near = block_index_.find(pack_cell(b.x() + dx, b.y() + dy, b.z() + dz));
        if (near != CellIndex::kAbsent) {
          block_flags_[near] |= flags;
        }
      }
    }
  }
}

namespace {

// A block's cells as a 64-bit mask, bit = x * 16 + y * 4 + z (bit_in_block): the cells at
// local coordinate 0 and 3 of each axis, and the bit distance of one step along it.
struct CellAxis {
  std::uint64_t low;   // coordinate 0
  std::uint64_t high;  // coordinate 3
  std::uint32_t step;
};
constexpr std::array<CellAxis, 3> kCellAxes{{{0x000000000000FFFFULL, 0xFFFF000000000000ULL, 16},
                                             {0x000F000F000F000FULL, 0xF000F000F000F000ULL, 4},
                                             {0x1111111111111111ULL, 0x8888888888888888ULL, 1}}};

// The cells within one step of `cells` along an axis, inside the block.
std::uint64_t dilated(std::uint64_t cells, const CellAxis& axis) noexcept {
  return cells | ((cells << axis.step) & ~axis.low) | ((cells >> axis.step) & ~axis.high);
}

}  // namespace

std::uint64_t VoxelGrid::stale_cells(const BlockNeighbourhood& around) noexcept {
  // A fine shape reads the 3 x 3 x 3 cells around its own: a cell is stale when a changed
  // cell lies among those, in this block or, at its faces, edges and corners, in the blocks
  // beside it. Per neighbouring block: its changed cells on this side, moved across
  // (coordinate 3 to 0 or 0 to 3), then spread one step along the axes the offset keeps.
  // (Neighbours that no live cell here faces were not looked up: their changes reach no
  // sample of this block.)
  std::uint64_t stale = 0;
  std::size_t k = 0;
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dz = -1; dz <= 1; ++dz, ++k) {
        const std::array<int, 3> offset{dx, dy, dz};
        std::uint64_t cells = around.changed[k];
        for (std::size_t a = 0; a < 3 && cells != 0; ++a) {
          const CellAxis& axis = kCellAxes[a];
          const std::uint32_t across = 3 * axis.step;
          if (offset[a] < 0) {
            cells = (cells & axis.high) >> across;
          } else if (offset[a] > 0) {
            cells = (cells & axis.low) << across;
          } else {
            cells = dilated(cells, axis);
          }
        }
        stale |= cells;
      }
    }
  }
  return stale;
}

void VoxelGrid::mark_stale_blocks() noexcept {
  for (std::size_t block = 0; block < block_count_; ++block) {
    if ((block_flags_[block] & kChanged) == 0) {
      continue;
    }
    // The blocks around may hold stale cells, and their coarse spreads read this block.
    mark_stale_around(block_keys_[block], kStale);
  }
}

void VoxelGrid::estimate_fine_shapes(const ShapeLimits& limits, bool every_sample_votes,
                                     std::span<std::uint32_t> voting_points,
                                     double& thickness_sum_m,
                                     std::uint64_t& planar_count) noexcept {
  shapes_reused_ = 0;
  if (keeping_shapes_) {
    mark_stale_blocks();
  }
  // Blocks that may hold stale cells (all of them without kept shapes): their neighbourhood
  // is looked up, and tells which cells are stale.
  const auto may_be_stale = [this](std::size_t i) {
    return !keeping_shapes_ || (block_flags_[block_order_[i].block] & (kStale | kAllStale)) != 0;
  };
  // Pipelined: the neighbourhood of the block kAhead places on is looked up (and its sums
  // fetched) while this block's samples are summed. A block whose shapes are kept needs none.
  constexpr std::size_t kAhead = 2;
  std::array<BlockNeighbourhood, kAhead + 1> ring;
  const auto look_up = [&](std::size_t i) {
    if (!may_be_stale(i)) {
      return;
    }
    const std::uint32_t block = block_order_[i].block;
    const auto b = unpack_cell(block_keys_[block]);
    load_neighbourhood(b.x(), b.y(), b.z(), live_masks_[block], ring[i % ring.size()]);
  };
  // The cells of block i whose fine shapes are estimated again.
  const auto stale_in = [&](std::size_t i) {
    const std::uint32_t block = block_order_[i].block;
    if (!may_be_stale(i)) {
      return std::uint64_t{0};
    }
    if (!keeping_shapes_ || (block_flags_[block] & kAllStale) != 0) {
      return ~std::uint64_t{0};
    }
    return stale_cells(ring[i % ring.size()]);
  };
  for (std::size_t i = 0; i < std::min(kAhead, block_count_); ++i) {
    look_up(i);
  }
  for (std::size_t i = 0; i < block_count_; ++i) {
    if (i + kAhead < block_count_) {
      look_up(i + kAhead);
    }
    const std::uint32_t block = block_order_[i].block;
    const BlockRange range = block_range(block);
    const BlockNeighbourhood& around = ring[i % ring.size()];
    const std::uint64_t stale = stale_in(i);
    // Samples read from the table have lost their shapes; moved ones carry them.
    const bool loaded = keeping_shapes_ && (block_flags_[block] & kLoaded) != 0;
    if (keeping_shapes_ && (stale & live_masks_[block]) != 0) {
      block_flags_[block] |= kReshaped;
    }
    // The block's samples are its live cells in bit order.
    std::uint64_t cells = live_masks_[block];
    float thickness_sum = 0.0f;  // per block in float, over the cloud in double
    std::uint32_t block_voting_points = 0;
    std::uint32_t block_scattered = 0;
    for (std::uint32_t id = range.first; id < range.first + range.count; ++id, cells &= cells - 1) {
      Voxel& voxel = voxels_[id];
      if ((stale & cells & (~cells + 1)) != 0) {
        voxel.fine_thickness_m = estimate_shape(voxel, around, limits);
        if (keeping_shapes_) {
          kept_[dense_serial_[id]] =
              KeptShape{voxel.axis, voxel.fine_thickness_m, voxel.shape, true};
        }
      } else {
        ++shapes_reused_;
        if (loaded) {
          // A new sample marks its cell changed, so a kept shape was estimated before.
          const KeptShape& kept = kept_[dense_serial_[id]];
          BLOCKMAP_CHECK_MSG(kept.valid, "a kept block holds a sample never estimated");
          voxel.shape = kept.shape;
          voxel.axis = kept.axis;
          voxel.fine_thickness_m = kept.thickness_m;
        } else if (voxel.coarse_look) {
          // What the coarse look made planar was scattered (it looks again below).
          voxel.shape = LocalShape::kScattered;
          voxel.axis = Eigen::Vector3f::UnitZ();
        }
      }
      voxel.coarse_look = false;
      // What the last detection left in the sample.
      voxel.owner = -1;
      voxel.axis_cell = kAxisCellUnknown;
      const float thickness_m = voxel.fine_thickness_m;
      const bool planar = voxel.shape == LocalShape::kPlanar;
      const bool linear = voxel.shape == LocalShape::kLinear;
      if (planar) {
        thickness_sum += thickness_m;
        ++planar_count;
      }
      block_scattered += voxel.shape == LocalShape::kScattered ? 1 : 0;
      shape_tally_.linear += linear ? 1 : 0;
      block_voting_points += every_sample_votes || planar || linear ? voxel.point_count : 0;
    }
    thickness_sum_m += static_cast<double>(thickness_sum);
    shape_tally_.scattered += block_scattered;
    block_summed_[block] = static_cast<std::uint8_t>((block_summed_[block] & ~kHoldsScattered) |
                                                     (block_scattered > 0 ? kHoldsScattered : 0));
    if (!voting_points.empty()) {
      voting_points[block] = block_voting_points;
    }
  }
}

namespace {

// Cells of a block by a 4-bit set of local coordinates along one axis (bit = x*16 + y*4 + z):
// `first` is the mask of the cells with coordinate 0 on that axis, `step` the bit distance
// between coordinates.
constexpr std::array<std::uint64_t, 16> cells_with(std::uint64_t first, std::uint32_t step) {
  std::array<std::uint64_t, 16> masks{};
  for (std::uint32_t set = 0; set < 16; ++set) {
    for (std::uint32_t c = 0; c < 4; ++c) {
      masks[set] |= ((set >> c) & 1U) != 0 ? first << (c * step) : 0;
    }
  }
  return masks;
}
constexpr std::array<std::uint64_t, 16> kCellsWithX = cells_with(0xFFFF, 16);
constexpr std::array<std::uint64_t, 16> kCellsWithY = cells_with(0x000F000F000F000F, 4);
constexpr std::array<std::uint64_t, 16> kCellsWithZ = cells_with(0x1111111111111111, 1);

// Along one axis, the cells within one of local coordinate `local` (0..3): in this block,
// and in the previous or next block when `local` is at a border.
struct AxisSpan {
  int block_offset = 0;      // -1, 0 or 1
  std::uint32_t locals = 0;  // 4-bit set of local coordinates in that block
};
std::size_t axis_spans(std::int64_t local, std::array<AxisSpan, 2>& out) noexcept {
  std::size_t count = 0;
  if (local == 0) {
    out[count++] = {-1, 0b1000U};
  }
  const std::int64_t low = std::max<std::int64_t>(local - 1, 0);
  const std::int64_t high = std::min<std::int64_t>(local + 1, 3);
  out[count++] = {0, ((2U << high) - 1U) & ~((1U << low) - 1U)};
  if (local == 3) {
    out[count++] = {1, 0b0001U};
  }
  return count;
}

// The eigenvalues of a symmetric 3 x 3 matrix, ascending, in closed form (the trigonometric
// solution of its characteristic cubic) and in float with polynomial trigonometry: the shape
// pass needs them for every sample (libm's acos and cos were a twentieth of the detection),
// and one eigenvector only when the shape is planar or linear. The ratio tests compare
// eigenvalues a factor of ten or more apart; float keeps them to a part in a million.
Eigen::Vector3f symmetric_eigenvalues(const Eigen::Matrix3f& a) noexcept {
  const float q = a.trace() / 3.0f;
  const float off = a(0, 1) * a(0, 1) + a(0, 2) * a(0, 2) + a(1, 2) * a(1, 2);
  const Eigen::Matrix3f shifted = a - q * Eigen::Matrix3f::Identity();
  const float p2 = (shifted.diagonal().squaredNorm() + 2.0f * off) / 6.0f;
  if (p2 <= 0.0f) {
    return Eigen::Vector3f::Constant(q);  // a multiple of the identity
  }
  const float p = std::sqrt(p2);
  const float r = std::clamp(shifted.determinant() / (2.0f * p2 * p), -1.0f, 1.0f);
  const float third = acos_signed(r) / 3.0f;  // in [0, pi/3]
  const float c = cos_small(third);
  const float s = sin_small(third);
  constexpr float kHalfSqrt3 = 0.8660254038f;
  const float largest = q + 2.0f * p * c;
  // cos(third + 2 pi / 3) = -cos(third) / 2 - sin(third) sqrt(3) / 2
  const float smallest = q - p * (c + 2.0f * kHalfSqrt3 * s);
  return {smallest, 3.0f * q - largest - smallest, largest};
}

// The unit eigenvector of symmetric `a` for `eigenvalue`, when that eigenvalue is well apart
// from the other two (the callers' ratio tests make sure): the rows of a - eigenvalue I span
// the plane perpendicular to it, so the largest cross product of two rows is the best
// conditioned estimate.
Eigen::Vector3f eigenvector_of(const Eigen::Matrix3f& a, float eigenvalue) noexcept {
  const Eigen::Matrix3f m = a - eigenvalue * Eigen::Matrix3f::Identity();
  const Eigen::Vector3f c01 = m.row(0).cross(m.row(1));
  const Eigen::Vector3f c02 = m.row(0).cross(m.row(2));
  const Eigen::Vector3f c12 = m.row(1).cross(m.row(2));
  const float n01 = c01.squaredNorm();
  const float n02 = c02.squaredNorm();
  const float n12 = c12.squaredNorm();
  const Eigen::Vector3f& best = n01 >= n02 ? (n01 >= n12 ? c01 : c12) : (n02 >= n12 ? c02 : c12);
  const float norm = best.norm();
  return norm > 0.0f ? Eigen::Vector3f(best / norm) : Eigen::Vector3f::UnitZ();
}

// The covariance of the points that `sums` add up, and its eigenvalues (ascending, >= 0).
struct Spread {
  Eigen::Matrix3f covariance;
  Eigen::Vector3f eigenvalues_m2;
};
[[gnu::always_inline]] inline Spread spread_of(const CentredSums& sums) noexcept {
  const std::array<float, 12>& v = sums.values;
  const float inverse_count = 1.0f / v[0];
  const Eigen::Vector3f mean = Eigen::Vector3f(v[1], v[2], v[3]) * inverse_count;
  Eigen::Matrix3f outer;
  outer << v[4], v[5], v[6], v[5], v[7], v[8], v[6], v[8], v[9];
  Spread spread;
  spread.covariance = outer * inverse_count - mean * mean.transpose();
  spread.eigenvalues_m2 = symmetric_eigenvalues(spread.covariance).cwiseMax(0.0f);
  return spread;
}

}  // namespace

VoxelGrid::CoarseSpread VoxelGrid::coarse_spread(std::int64_t bx, std::int64_t by, std::int64_t bz,
                                                 const ShapeLimits* limits) noexcept {
  CentredSums around;
  const float block_m = size_m_ * static_cast<float>(kBlockEdge);
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dz = -1; dz <= 1; ++dz) {
        const std::uint32_t block = block_index_.find(pack_cell(bx + dx, by + dy, bz + dz));
        if (block == CellIndex::kAbsent) {
          continue;
        }
        if ((block_summed_[block] & kSummed) == 0) {
          block_sums_[block] = sum_block(block);
          block_summed_[block] |= kSummed;
        }
        around.add(block_sums_[block].moved_by({static_cast<float>(dx) * block_m,
                                                static_cast<float>(dy) * block_m,
                                                static_cast<float>(dz) * block_m}));
      }
    }
  }
  CoarseSpread out;
  out.point_count = around.values[0];
  if (limits != nullptr && around.values[0] < limits->min_points) {
    return out;
  }
  const Spread spread = spread_of(around);
  out.thickness_m2 = spread.eigenvalues_m2(0);
  out.width_m2 = spread.eigenvalues_m2(1);
  // The eigenvector only when some limits could take it (without limits: always, to keep).
  if (limits == nullptr || coarse_normal_of(out, *limits, true)) {
    out.normal = eigenvector_of(spread.covariance, out.thickness_m2);
  }
  return out;
}

bool VoxelGrid::coarse_normal_of(const CoarseSpread& spread, const ShapeLimits& limits,
                                 bool ignoring_normal) noexcept {
  if (spread.point_count < limits.min_points) {
    return false;
  }
  const float l0 = spread.thickness_m2;
  const float l1 = spread.width_m2;
  const bool planar = l0 <= limits.planar_ratio_sq * l1;
  const bool noisy_slab =
      l0 <= limits.noisy_slab_ratio_sq * l1 && l0 <= limits.noisy_slab_thickness_m2;
  if (!planar && !noisy_slab) {
    return false;
  }
  // A noisy slab is a wall only: a level laser's returns on everything it crosses (walls,
  // cars, bushes) lie in a horizontal sheet as thick as its pitch noise, a false floor.
  constexpr float kMaxSlabNormalZ = 0.5f;  // the normal at least 30 deg off vertical
  return planar || ignoring_normal || std::abs(spread.normal.z()) <= kMaxSlabNormalZ;
}

Eigen::Vector3f VoxelGrid::coarse_normal(std::uint32_t block, const ShapeLimits& limits) noexcept {
  const auto b = unpack_cell(block_keys_[block]);
  if (!keeping_shapes_) {
    const CoarseSpread spread = coarse_spread(b.x(), b.y(), b.z(), &limits);
    return coarse_normal_of(spread, limits, false) ? spread.normal : Eigen::Vector3f::Zero();
  }
  // Kept: the spread of the blocks around changes only when one of them did (a stale block);
  // the limits follow the cloud's surface noise, so they are applied anew.
  CoarseSpread& kept = kept_coarse_[block];
  if (!kept.known || (block_flags_[block] & kStale) != 0) {
    const Eigen::Vector3f normal_before = kept.normal;
    const bool known_before = kept.known;
    kept = coarse_spread(b.x(), b.y(), b.z(), nullptr);
    kept.known = true;
    if (!known_before || kept.normal != normal_before) {
      block_flags_[block] |= kReshaped;  // what the coarse look gives may have moved
    }
  }
  return coarse_normal_of(kept, limits, false) ? kept.normal : Eigen::Vector3f::Zero();
}

float VoxelGrid::estimate_shape(Voxel& voxel, const BlockNeighbourhood& around,
                                const ShapeLimits& limits) const noexcept {
  const auto cell = unpack_cell(voxel.key);
  std::array<AxisSpan, 2> xs;
  std::array<AxisSpan, 2> ys;
  std::array<AxisSpan, 2> zs;
  const std::size_t nx = axis_spans(cell.x() & 3, xs);
  const std::size_t ny = axis_spans(cell.y() & 3, ys);
  const std::size_t nz = axis_spans(cell.z() & 3, zs);
  // The neighbourhood's moments about this block's centre, summed over the occupied cells
  // only: the set bits of each neighbouring block's live mask inside the 3 x 3 x 3 box
  // (testing all 27 cells mispredicted a branch on every other one). A neighbouring block's
  // cells are summed about its own centre first and moved once.
  const float block_m = size_m_ * static_cast<float>(kBlockEdge);
  CentredSums total;
  for (std::size_t i = 0; i < nx; ++i) {
    for (std::size_t j = 0; j < ny; ++j) {
      for (std::size_t k = 0; k < nz; ++k) {
        const int which_signed =
            (xs[i].block_offset + 1) * 9 + (ys[j].block_offset + 1) * 3 + zs[k].block_offset + 1;
        const auto which = static_cast<std::size_t>(which_signed);
        const std::uint64_t live = around.live_masks[which];
        std::uint64_t cells = live & kCellsWithX[xs[i].locals] & kCellsWithY[ys[j].locals] &
                              kCellsWithZ[zs[k].locals];
        if (cells == 0) {
          continue;
        }
        CentredSums part;
        for (; cells != 0; cells &= cells - 1) {
          const auto bit = static_cast<std::uint32_t>(std::countr_zero(cells));
          // The cell's id: its block's first id plus the live cells before it in bit order.
          part.add(
              centred_sums_[around.first[which] + static_cast<std::uint32_t>(std::popcount(
                                                      live & ((std::uint64_t{1} << bit) - 1)))]);
        }
        if (which == kOwnBlock) {
          total.add(part);
        } else {
          total.add(part.moved_by({static_cast<float>(xs[i].block_offset) * block_m,
                                   static_cast<float>(ys[j].block_offset) * block_m,
                                   static_cast<float>(zs[k].block_offset) * block_m}));
        }
      }
    }
  }
  // A shape without an axis gets the axis of a sample laid out afresh: compact() moves
  // unchanged blocks' samples with what the last estimate left in them.
  if (total.values[0] < limits.min_points) {
    voxel.shape = LocalShape::kTooFewPoints;
    voxel.axis = Eigen::Vector3f::UnitZ();
    return 0.0f;
  }
  const Spread spread = spread_of(total);
  const Eigen::Vector3f& l = spread.eigenvalues_m2;
  float thickness_m = 0.0f;
  if (l(1) <= limits.line_ratio_sq * l(2)) {
    // Thin in two directions: points along one line (a scan line on a far surface).
    voxel.shape = LocalShape::kLinear;
    voxel.axis = eigenvector_of(spread.covariance, l(2));
  } else if (l(0) <= limits.planar_ratio_sq * l(1)) {
    // Wide in two directions, thin in the third: a surface.
    voxel.shape = LocalShape::kPlanar;
    voxel.axis = eigenvector_of(spread.covariance, l(0));
    thickness_m = std::sqrt(l(0));
    // Within 10 deg of vertical: flat only because a level laser's slice holds its points.
    // Its shape within the slice decides: at most half as wide across as along, the trace of
    // a wall (a trunk's or a bush's is round).
    constexpr float kCosLevelSlice = 0.985F;
    constexpr float kTraceRatioSq = 0.25F;
    if (limits.level_slices && std::abs(voxel.axis.z()) >= kCosLevelSlice) {
      const bool trace = l(1) <= kTraceRatioSq * l(2);
      voxel.shape = trace ? LocalShape::kLinear : LocalShape::kScattered;
      voxel.axis = eigenvector_of(spread.covariance, l(2));
    }
  } else {
    voxel.shape = LocalShape::kScattered;
    voxel.axis = Eigen::Vector3f::UnitZ();
  }
  return thickness_m;
}

}  // namespace blockmap::planes
