// The mapper's sliding window: the voxel samples of the space around the robot, in square
// columns of space (tiles) laid out in a ring of tiles_across x tiles_across slots indexed
// modulo its size, so that the window scrolls with the robot without moving what it holds. A
// tile that falls out of the window is handed to the caller (its samples are the last the map
// sees of that ground) and its samples go back to the free list.
//
// A sample keeps what plane fitting needs, not points: the point count and the first and
// second moments about the voxel's centre (planes::VoxelSums, the plane detector's own
// layout). Samples come from one pool sized at init and shared by all tiles (a street's tiles
// hold tens of samples, a tile with a tall facade thousands); a tile's samples are a chain
// through the pool, and a hash table with deletion finds a point's voxel. Nothing allocates
// after init(); a point that finds the pool full is dropped and counted.
//
// A window may reach farther than its pool can hold everywhere: the tiles beyond a core
// around the robot then leave early when the pool runs low (make_room), those that scans
// touched least recently first, and take no points until the robot comes near them again.
// Where the map is sparse it reaches across the whole ring; where it is dense it holds what
// the core does.
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <string>
#include <utility>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "blockmap/core/arena.hpp"
#include "blockmap/planes/voxel_grid.hpp"

namespace blockmap::map {

struct VoxelWindowConfig {
  // The plane detector's sample edge (planes::PlanesConfig::sample_size_m).
  double voxel_size_m = 0.2;
  // A whole number of voxels, and of the detector's section strides (4 voxels), so that no
  // block of the detector straddles two tiles.
  double tile_size_m = 8.0;
  // Odd: the robot's tile is the middle one. 7 tiles of 8 m reach 24-32 m beyond the robot;
  // returns beyond the edge are counted and dropped (the robot maps them as it comes nearer).
  std::uint32_t tiles_across = 7;
  // Room for the peaks of the simulated usc_block and benning (docs/mapper.md).
  std::size_t max_samples = 81920;
  // The tiles around the robot that keep their samples until they leave the window (odd, at
  // most tiles_across; 0: every tile). When fewer than reserve_samples of the pool are free,
  // make_room() lets the tiles beyond them leave early, least recently touched first; such a
  // tile takes no points until it comes within the core or leaves the window.
  std::uint32_t core_tiles_across = 0;
  // With a core: the free samples kept for the next scans' new voxels (a scan of 361 beams
  // makes at most 361), less than max_samples.
  std::size_t reserve_samples = 4096;
};

// Empty when usable, otherwise what is wrong.
[[nodiscard]] std::string validate(const VoxelWindowConfig& config);

struct VoxelWindowCounters {
  std::uint64_t points_added = 0;
  std::uint64_t points_outside = 0;       // beyond the window's edge: dropped
  std::uint64_t points_dropped_full = 0;  // a new voxel, and the pool full
  std::uint64_t points_non_finite = 0;
  std::uint64_t tiles_evicted = 0;           // every tile that left, early ones included
  std::uint64_t tiles_left_early = 0;        // beyond the core, for room (make_room)
  std::uint64_t points_in_closed_tiles = 0;  // in a tile that left early: dropped
  std::uint64_t samples_evicted = 0;
  std::size_t peak_samples = 0;
};

class VoxelWindow {
 public:
  // A tile leaving the window: its square in the local frame and its samples, a chunk at a
  // time (at most kEvictionChunk each).
  static constexpr std::size_t kEvictionChunk = 1024;
  struct EvictedTile {
    Eigen::AlignedBox2d bounds_m;
    double voxel_size_m = 0.0;
    std::span<const planes::VoxelSums> samples;
  };
  // Called for each chunk of each tile that leaves the window.
  class EvictionSink {
   public:
    EvictionSink() = default;
    EvictionSink(const EvictionSink&) = default;
    EvictionSink& operator=(const EvictionSink&) = default;
    virtual ~EvictionSink() = default;
    virtual void on_evicted(const EvictedTile& tile) noexcept = 0;
  };

  void init(Arena& arena, const VoxelWindowConfig& config);
  [[nodiscard]] static std::size_t arena_bytes(const VoxelWindowConfig& config) noexcept;

  // Centres the window on the tile holding position_m. Tiles that fall out of it are handed to
  // `sink` and forgotten; the first call only places the window. Cost: the evicted samples.
  void recentre(const Eigen::Vector2d& position_m, EvictionSink& sink) noexcept;
  // While fewer than reserve_samples are free, the tile beyond the core that points reached
  // least recently (the first such slot on a tie) leaves, handed to `sink`, and is closed:
  // its points are dropped and counted until it comes within the core (recentre() opens it)
  // or leaves the window. Nothing without a core smaller than the window. Cost: a pass over
  // the tile slots per tile that leaves, and the samples that leave.
  void make_room(EvictionSink& sink) noexcept;
  [[nodiscard]] bool placed() const noexcept { return placed_; }
  // The window's square in the local frame (empty before the first recentre()).
  [[nodiscard]] Eigen::AlignedBox2d bounds_m() const noexcept;

  // A point in the local frame; dropped and counted when outside the window, non-finite, or
  // in a new voxel when the pool is full.
  void add_point(const Eigen::Vector3f& point_m) noexcept;
  void add_points(std::span<const Eigen::Vector3f> points_m) noexcept;

  // Every sample in the window, tile slot by tile slot: the same points in the same order
  // give the same sequence.
  template <typename Visit>  // void(const planes::VoxelSums&)
  void for_each_sample(Visit&& visit) const {
    for (const TileSlot& slot : slots_) {
      for (std::uint32_t i = slot.first; i != kNone; i = next_[i]) {
        visit(samples_[i]);
      }
    }
  }

  // The samples that gained points since forget_touched() (each once), in the order they
  // first did; a tile that left since may have taken some (those are skipped). `ahead` sees
  // each sample a few visits before `visit` does, to fetch what the visit will read.
  template <typename Visit, typename Ahead>  // void(const planes::VoxelSums&), both
  void for_each_touched(Visit&& visit, Ahead&& ahead) const {
    constexpr std::size_t kAhead = 8;
    for (std::size_t i = 0; i < std::min(kAhead, touched_count_); ++i) {
      ahead(samples_[touched_[i]]);
    }
    for (std::size_t i = 0; i < touched_count_; ++i) {
      if (i + kAhead < touched_count_) {
        ahead(samples_[touched_[i + kAhead]]);
      }
      const planes::VoxelSums& sample = samples_[touched_[i]];
      if (sample.key != planes::kNoCell) {
        visit(sample);
      }
    }
  }
  template <typename Visit>  // void(const planes::VoxelSums&)
  void for_each_touched(Visit&& visit) const {
    for_each_touched(std::forward<Visit>(visit), [](const planes::VoxelSums&) {});
  }
  void forget_touched() noexcept;

  [[nodiscard]] std::size_t size() const noexcept { return sample_count_; }
  [[nodiscard]] std::size_t capacity() const noexcept { return samples_.size(); }
  [[nodiscard]] const VoxelWindowConfig& config() const noexcept { return config_; }
  [[nodiscard]] const VoxelWindowCounters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept {
    return slots_.size_bytes() + samples_.size_bytes() + next_.size_bytes() + table_.size_bytes() +
           chunk_.size_bytes() + touched_.size_bytes() + touched_flag_.size_bytes();
  }

 private:
  static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
  struct TileSlot {
    std::int64_t tile_x = 0;  // the tile this slot holds (meaningful when it holds samples)
    std::int64_t tile_y = 0;
    std::uint32_t first = kNone;  // its samples' chain through the pool
    std::uint32_t count = 0;
    std::uint64_t touched_batch = 0;  // the add_points() call that last reached it
    bool closed = false;              // left early (make_room): takes no points
  };
  struct TableSlot {
    planes::CellKey key = planes::kNoCell;
    std::uint32_t sample = kNone;
  };

  [[nodiscard]] std::int64_t tile_of_voxel(std::int64_t voxel) const noexcept;
  [[nodiscard]] std::size_t slot_of_tile(std::int64_t tile_x, std::int64_t tile_y) const noexcept;
  [[nodiscard]] bool tile_inside(std::int64_t tile_x, std::int64_t tile_y) const noexcept;
  [[nodiscard]] bool tile_in_core(std::int64_t tile_x, std::int64_t tile_y) const noexcept;
  [[nodiscard]] Eigen::AlignedBox2d tile_bounds_m(std::int64_t tile_x,
                                                  std::int64_t tile_y) const noexcept;
  // The sample of `key` (in tile slot `slot`), created when new; kNone when the pool is full.
  [[nodiscard]] std::uint32_t find_or_create(planes::CellKey key, TileSlot& slot) noexcept;
  [[nodiscard]] std::size_t home_of(planes::CellKey key) const noexcept;
  // The slot holding `key`, or the empty slot where it would go.
  [[nodiscard]] std::size_t probe_table(planes::CellKey key) const noexcept;
  void erase_key(planes::CellKey key) noexcept;
  void evict(TileSlot& slot, EvictionSink& sink) noexcept;

  VoxelWindowConfig config_;
  float inverse_voxel_m_ = 5.0f;
  std::int64_t voxels_per_tile_ = 40;
  std::int64_t half_tiles_ = 5;
  std::int64_t core_half_tiles_ = 5;
  std::uint64_t batch_ = 0;  // add_points() calls so far
  bool placed_ = false;
  std::int64_t centre_tile_x_ = 0;
  std::int64_t centre_tile_y_ = 0;
  std::span<TileSlot> slots_;
  std::span<planes::VoxelSums> samples_;
  std::span<std::uint32_t> next_;  // the chain of a tile's samples, and the free list
  std::uint32_t free_first_ = kNone;
  std::size_t sample_count_ = 0;
  // Linear probing, at most two thirds full (table_slots); deletion shifts back.
  std::span<TableSlot> table_;
  std::uint32_t table_shift_ = 64;
  std::span<planes::VoxelSums> chunk_;  // an evicted tile's samples, gathered for the sink
  // Samples that gained points since forget_touched(): their pool indexes, and a flag each.
  std::span<std::uint32_t> touched_;
  std::size_t touched_count_ = 0;
  std::span<std::uint8_t> touched_flag_;
  // The voxel of the last point added, and its sample (kNoCell after an eviction).
  planes::CellKey last_key_ = planes::kNoCell;
  std::uint32_t last_sample_ = kNone;
  VoxelWindowCounters counters_;
};

}  // namespace blockmap::map
