#include "blockmap/planes/voxel_grid.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <iterator>

#include "blockmap/core/check.hpp"
#include "blockmap/core/linear_probing.hpp"

namespace blockmap::planes {

void VoxelGrid::init(Arena& arena, double voxel_size_m, std::size_t max_voxels,
                     std::size_t max_blocks) {
  BLOCKMAP_CHECK_MSG(voxel_size_m > 0.0 && max_voxels > 0, "voxel size and capacity must be > 0");
  voxel_size_m_ = voxel_size_m;
  inverse_size_ = static_cast<float>(1.0 / voxel_size_m);
  size_m_ = static_cast<float>(voxel_size_m);
  const std::size_t slots = half_full_slots(max_voxels);
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
  const std::size_t slots = half_full_slots(max_voxels);
  constexpr std::size_t kAlignment = Arena::kMaxPaddingBytes;
  return slots * sizeof(std::uint32_t) +
         max_voxels * (2 * sizeof(std::uint32_t) + sizeof(KeptShape)) +
         blocks * (sizeof(std::uint8_t) + sizeof(std::uint64_t) + sizeof(CoarseSpread)) +
         7 * kAlignment;
}

std::size_t VoxelGrid::arena_bytes(std::size_t max_voxels, std::size_t max_blocks) noexcept {
  const std::size_t blocks = max_blocks == 0 ? max_voxels : max_blocks;
  const std::size_t slots = half_full_slots(max_voxels);
  constexpr std::size_t kAlignment = Arena::kMaxPaddingBytes;
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

std::uint32_t VoxelGrid::find_or_create(CellKey key) noexcept {
  const std::size_t slot = probe_table(key);
  VoxelSums& voxel = table_[slot];
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
  }
  return static_cast<std::uint32_t>(slot);
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

}  // namespace blockmap::planes
