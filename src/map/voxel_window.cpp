#include "blockmap/map/voxel_window.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

#include "blockmap/core/check.hpp"
#include "blockmap/core/floor_div.hpp"
#include "blockmap/core/linear_probing.hpp"

namespace blockmap::map {
namespace {

// At most two thirds full: a key is found in about 2 probes and missed in 5, at the worst,
// with the multiplicative hash below. Twice the samples, rounded up, took 4 MiB of the
// default window's 64 MiB where this takes 2, at the same speed on benning. (The detector's
// table stays at half: its hash keeps a block's cells together, on purpose, and those runs
// grow long when fuller.)
std::size_t table_slots(std::size_t max_samples) noexcept {
  return std::bit_ceil(std::max<std::size_t>(max_samples + max_samples / 2, 16));
}

// A whole number near `ratio`, or 0 when it is not one.
std::int64_t whole(double ratio) noexcept {
  const double rounded = std::round(ratio);
  return std::abs(ratio - rounded) < 1e-6 ? static_cast<std::int64_t>(rounded) : 0;
}

// A point's voxel coordinates, floored, fit an int64 key field only this far out: a float
// beyond it is checked before it is converted (a huge float does not fit an int64).
constexpr auto kFarVoxels = static_cast<float>(2 * planes::kCellKeyBias);

bool fits_a_key(const Eigen::Vector3f& floored) noexcept {
  return floored.cwiseAbs().maxCoeff() < kFarVoxels;
}

}  // namespace

std::string validate(const VoxelWindowConfig& config) {
  if (!(config.voxel_size_m > 0.0) || !(config.tile_size_m > 0.0)) {
    return "window: voxel_size_m and tile_size_m must be positive";
  }
  const std::int64_t voxels = whole(config.tile_size_m / config.voxel_size_m);
  if (voxels == 0 || voxels % planes::kBlockEdge != 0) {
    return "window: tile_size_m must be a whole number of 4-voxel blocks (voxel_size_m * 4)";
  }
  if (config.tiles_across < 3 || config.tiles_across % 2 == 0 || config.tiles_across > 255) {
    return "window: tiles_across must be odd, from 3 to 255";
  }
  if (config.max_samples < 64 || config.max_samples >= (std::size_t{1} << 31)) {
    return "window: max_samples must be from 64 to 2^31";
  }
  if (config.core_tiles_across != 0 &&
      (config.core_tiles_across % 2 == 0 || config.core_tiles_across > config.tiles_across)) {
    return "window: core_tiles_across must be 0 (every tile) or odd and at most tiles_across";
  }
  if (config.core_tiles_across != 0 && config.reserve_samples >= config.max_samples) {
    return "window: reserve_samples must be less than max_samples";
  }
  return {};
}

void VoxelWindow::init(Arena& arena, const VoxelWindowConfig& config) {
  const std::string problem = validate(config);
  BLOCKMAP_CHECK_MSG(problem.empty(), "an invalid window configuration reached init()");
  config_ = config;
  last_key_ = planes::kNoCell;
  inverse_voxel_m_ = static_cast<float>(1.0 / config.voxel_size_m);
  voxels_per_tile_ = whole(config.tile_size_m / config.voxel_size_m);
  half_tiles_ = static_cast<std::int64_t>(config.tiles_across / 2);
  core_half_tiles_ = config.core_tiles_across == 0
                         ? half_tiles_
                         : static_cast<std::int64_t>(config.core_tiles_across / 2);
  batch_ = 0;
  slots_ = arena.allocate_array<TileSlot>(std::size_t{config.tiles_across} * config.tiles_across,
                                          "window.tiles");
  samples_ = arena.allocate_array<planes::VoxelSums>(config.max_samples, "window.samples");
  next_ = arena.allocate_array<std::uint32_t>(config.max_samples, "window.chains");
  const std::size_t slots = table_slots(config.max_samples);
  table_ = arena.allocate_array<TableSlot>(slots, "window.index");
  table_shift_ = 64U - static_cast<std::uint32_t>(std::countr_zero(slots));
  chunk_ = arena.allocate_array<planes::VoxelSums>(kEvictionChunk, "window.eviction_chunk");
  touched_ = arena.allocate_array<std::uint32_t>(config.max_samples, "window.touched");
  touched_flag_ = arena.allocate_array<std::uint8_t>(config.max_samples, "window.touched");
  // Every sample is free: the free list runs through the pool in order.
  for (std::size_t i = 0; i < next_.size(); ++i) {
    next_[i] = i + 1 < next_.size() ? static_cast<std::uint32_t>(i + 1) : kNone;
  }
  free_first_ = 0;
}

std::size_t VoxelWindow::arena_bytes(const VoxelWindowConfig& config) noexcept {
  constexpr std::size_t kSlack = 64;  // alignment of each array
  return std::size_t{config.tiles_across} * config.tiles_across * sizeof(TileSlot) +
         config.max_samples * (sizeof(planes::VoxelSums) + sizeof(std::uint32_t)) +
         table_slots(config.max_samples) * sizeof(TableSlot) +
         kEvictionChunk * sizeof(planes::VoxelSums) +
         config.max_samples * (sizeof(std::uint32_t) + sizeof(std::uint8_t)) + 7 * kSlack;
}

std::int64_t VoxelWindow::tile_of_voxel(std::int64_t voxel) const noexcept {
  return floor_div(voxel, voxels_per_tile_);
}

std::size_t VoxelWindow::slot_of_tile(std::int64_t tile_x, std::int64_t tile_y) const noexcept {
  const auto across = static_cast<std::int64_t>(config_.tiles_across);
  const std::int64_t column = ((tile_x % across) + across) % across;
  const std::int64_t row = ((tile_y % across) + across) % across;
  return static_cast<std::size_t>(row * across + column);
}

bool VoxelWindow::tile_inside(std::int64_t tile_x, std::int64_t tile_y) const noexcept {
  return placed_ && std::abs(tile_x - centre_tile_x_) <= half_tiles_ &&
         std::abs(tile_y - centre_tile_y_) <= half_tiles_;
}

bool VoxelWindow::tile_in_core(std::int64_t tile_x, std::int64_t tile_y) const noexcept {
  return placed_ && std::abs(tile_x - centre_tile_x_) <= core_half_tiles_ &&
         std::abs(tile_y - centre_tile_y_) <= core_half_tiles_;
}

Eigen::AlignedBox2d VoxelWindow::tile_bounds_m(std::int64_t tile_x,
                                               std::int64_t tile_y) const noexcept {
  const Eigen::Vector2d low(static_cast<double>(tile_x) * config_.tile_size_m,
                            static_cast<double>(tile_y) * config_.tile_size_m);
  return {low, low + Eigen::Vector2d::Constant(config_.tile_size_m)};
}

Eigen::AlignedBox2d VoxelWindow::bounds_m() const noexcept {
  if (!placed_) {
    return {};
  }
  Eigen::AlignedBox2d box =
      tile_bounds_m(centre_tile_x_ - half_tiles_, centre_tile_y_ - half_tiles_);
  box.extend(tile_bounds_m(centre_tile_x_ + half_tiles_, centre_tile_y_ + half_tiles_));
  return box;
}

void VoxelWindow::recentre(const Eigen::Vector2d& position_m, EvictionSink& sink) noexcept {
  const auto tile_x = static_cast<std::int64_t>(std::floor(position_m.x() / config_.tile_size_m));
  const auto tile_y = static_cast<std::int64_t>(std::floor(position_m.y() / config_.tile_size_m));
  if (placed_ && tile_x == centre_tile_x_ && tile_y == centre_tile_y_) {
    return;
  }
  placed_ = true;
  centre_tile_x_ = tile_x;
  centre_tile_y_ = tile_y;
  // A slot whose tile is no longer inside is the slot of a tile now inside (the ring): its
  // samples leave first.
  for (TileSlot& slot : slots_) {
    if (slot.count > 0 && !tile_inside(slot.tile_x, slot.tile_y)) {
      evict(slot, sink);
    } else if (slot.closed && !tile_inside(slot.tile_x, slot.tile_y)) {
      slot = TileSlot{};  // a closed tile that left: its slot holds the tile now inside
    }
    // The robot came near a tile that left early: it maps it again.
    if (slot.closed && tile_in_core(slot.tile_x, slot.tile_y)) {
      slot.closed = false;
    }
  }
}

void VoxelWindow::make_room(EvictionSink& sink) noexcept {
  if (!placed_ || core_half_tiles_ >= half_tiles_) {
    return;
  }
  while (samples_.size() - sample_count_ < config_.reserve_samples) {
    TileSlot* stalest = nullptr;
    for (TileSlot& slot : slots_) {
      if (slot.count > 0 && !tile_in_core(slot.tile_x, slot.tile_y) &&
          (stalest == nullptr || slot.touched_batch < stalest->touched_batch)) {
        stalest = &slot;
      }
    }
    if (stalest == nullptr) {
      return;  // the core alone fills the pool: new voxels are dropped, as without a core
    }
    const std::int64_t tile_x = stalest->tile_x;
    const std::int64_t tile_y = stalest->tile_y;
    evict(*stalest, sink);
    stalest->tile_x = tile_x;
    stalest->tile_y = tile_y;
    stalest->closed = true;
    ++counters_.tiles_left_early;
  }
}

void VoxelWindow::evict(TileSlot& slot, EvictionSink& sink) noexcept {
  last_key_ = planes::kNoCell;  // its sample may be one of these
  const Eigen::AlignedBox2d bounds = tile_bounds_m(slot.tile_x, slot.tile_y);
  std::size_t gathered = 0;
  std::uint32_t i = slot.first;
  while (i != kNone) {
    chunk_[gathered++] = samples_[i];
    erase_key(samples_[i].key);
    samples_[i].key = planes::kNoCell;
    const std::uint32_t after = next_[i];
    next_[i] = free_first_;  // back onto the free list
    free_first_ = i;
    i = after;
    if (gathered == chunk_.size() || i == kNone) {
      sink.on_evicted(EvictedTile{bounds, config_.voxel_size_m, chunk_.first(gathered)});
      gathered = 0;
    }
  }
  counters_.tiles_evicted += 1;
  counters_.samples_evicted += slot.count;
  sample_count_ -= slot.count;
  slot = TileSlot{};
}

std::size_t VoxelWindow::home_of(planes::CellKey key) const noexcept {
  return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> table_shift_);
}

std::uint32_t VoxelWindow::find_or_create(planes::CellKey key, TileSlot& slot) noexcept {
  const std::size_t at = probe_table(key);
  if (table_[at].key == key) {
    return table_[at].sample;
  }
  if (free_first_ == kNone) {
    return kNone;
  }
  const std::uint32_t sample = free_first_;
  free_first_ = next_[sample];
  samples_[sample] = planes::VoxelSums{};
  samples_[sample].key = key;
  next_[sample] = slot.first;
  slot.first = sample;
  ++slot.count;
  table_[at] = TableSlot{key, sample};
  ++sample_count_;
  counters_.peak_samples = std::max(counters_.peak_samples, sample_count_);
  return sample;
}

std::size_t VoxelWindow::probe_table(planes::CellKey key) const noexcept {
  return probe(
      home_of(key), table_.size() - 1,
      [this](std::size_t at) { return table_[at].key == planes::kNoCell; },
      [this, key](std::size_t at) { return table_[at].key == key; });
}

void VoxelWindow::erase_key(planes::CellKey key) noexcept {
  const std::size_t mask = table_.size() - 1;
  const std::size_t hole = probe_table(key);
  if (table_[hole].key != key) {
    return;
  }
  erase_shifting_back(
      hole, mask, [this](std::size_t at) { return table_[at].key != planes::kNoCell; },
      [this](std::size_t at) { return home_of(table_[at].key); },
      [this](std::size_t from, std::size_t to) { table_[to] = table_[from]; },
      [this](std::size_t at) { table_[at] = TableSlot{}; });
}

void VoxelWindow::add_point(const Eigen::Vector3f& point_m) noexcept {
  if (!point_m.allFinite()) {
    ++counters_.points_non_finite;
    return;
  }
  const Eigen::Vector3f floored = (point_m * inverse_voxel_m_).array().floor();
  if (!fits_a_key(floored)) {
    ++counters_.points_outside;
    return;
  }
  const auto x = static_cast<std::int64_t>(floored.x());
  const auto y = static_cast<std::int64_t>(floored.y());
  const auto z = static_cast<std::int64_t>(floored.z());
  const std::int64_t tile_x = tile_of_voxel(x);
  const std::int64_t tile_y = tile_of_voxel(y);
  if (!tile_inside(tile_x, tile_y) || !planes::cell_in_range(x, y, z)) {
    ++counters_.points_outside;
    return;
  }
  TileSlot& slot = slots_[slot_of_tile(tile_x, tile_y)];
  if (slot.closed) {
    ++counters_.points_in_closed_tiles;
    return;
  }
  if (slot.count == 0) {
    slot.tile_x = tile_x;
    slot.tile_y = tile_y;
  }
  slot.touched_batch = batch_;
  // Neighbouring beams of a scan often land in one voxel: the last one found is kept.
  const planes::CellKey key = planes::pack_cell(x, y, z);
  if (key != last_key_) {
    const std::uint32_t found = find_or_create(key, slot);
    if (found == kNone) {
      ++counters_.points_dropped_full;
      return;
    }
    last_key_ = key;
    last_sample_ = found;
  }
  const std::uint32_t sample = last_sample_;
  // The detector's layout: sums about the voxel's centre (computed as VoxelGrid::centre_m
  // does), in metres.
  const Eigen::Vector3f centre_m =
      ((Eigen::Vector3d(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z))
            .array() +
        0.5) *
       config_.voxel_size_m)
          .matrix()
          .cast<float>();
  const Eigen::Vector3f local = point_m - centre_m;
  if (touched_flag_[sample] == 0) {
    touched_flag_[sample] = 1;
    touched_[touched_count_++] = sample;
  }
  samples_[sample].add_point_m(local);
  ++counters_.points_added;
}

void VoxelWindow::forget_touched() noexcept {
  for (std::size_t i = 0; i < touched_count_; ++i) {
    touched_flag_[touched_[i]] = 0;
  }
  touched_count_ = 0;
}

void VoxelWindow::add_points(std::span<const Eigen::Vector3f> points_m) noexcept {
  // In batches: the table slot of each change of voxel in a batch is fetched first, and the
  // points are summed while the fetches arrive (the table is MiBs, read at random: a new
  // voxel was a cache miss, a twentieth of the benning replay).
  constexpr std::size_t kBatch = 32;
  ++batch_;
  for (std::size_t first = 0; first < points_m.size(); first += kBatch) {
    const std::span<const Eigen::Vector3f> batch =
        points_m.subspan(first, std::min(kBatch, points_m.size() - first));
    planes::CellKey fetched = last_key_;
    for (const Eigen::Vector3f& point : batch) {
      const Eigen::Vector3f floored = (point * inverse_voxel_m_).array().floor();
      if (!point.allFinite() || !fits_a_key(floored)) {
        continue;
      }
      const planes::CellKey key = planes::pack_cell(static_cast<std::int64_t>(floored.x()),
                                                    static_cast<std::int64_t>(floored.y()),
                                                    static_cast<std::int64_t>(floored.z()));
      if (key != fetched) {
        fetched = key;
        __builtin_prefetch(&table_[home_of(key)]);
      }
    }
    for (const Eigen::Vector3f& point : batch) {
      add_point(point);
    }
  }
}

}  // namespace blockmap::map
