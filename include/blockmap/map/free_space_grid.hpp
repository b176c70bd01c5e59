// Where a level laser has seen through: a 2D grid of the ground, each cell counting the beams
// that passed through it and those that ended in it. A building block the robot drove around
// is then the region inside its path that no beam ever crossed (buildings::BlockTracer), which
// tells the block's outline where its walls do not: behind trees, at steps no wall was seen on.
//
// The grid is a ring of tiles_across x tiles_across square tiles indexed modulo its size, like
// the voxel window, so that it follows the robot without moving what it holds: a tile whose
// slot is wanted for other ground is cleared and taken. Each cell is two saturating bytes;
// nothing allocates after init().
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include <Eigen/Core>

#include "blockmap/core/arena.hpp"

namespace blockmap::map {

struct FreeSpaceConfig {
  // 0 turns the grid off (no memory taken, nothing carved).
  std::uint32_t tiles_across = 0;
  double cell_size_m = 0.5;
  static constexpr std::uint32_t kCellsPerTile = 32;  // a tile's side, in cells
  // A beam carves up to this short of its return: the wall's own cell (the range noise, the
  // pose's error across the beam) stays out of the free space.
  double stop_short_m = 0.75;
  // A cell is free when at least this many beams passed through it and they outnumber the
  // returns in it by free_pass_ratio (a gap in a hedge lets a few beams through).
  std::uint8_t min_passes = 2;
  double free_pass_ratio = 2.0;
};

// Empty when usable, otherwise what is wrong.
[[nodiscard]] std::string validate(const FreeSpaceConfig& config);

struct FreeSpaceCounters {
  std::uint64_t beams = 0;
  std::uint64_t cells_crossed = 0;
  std::uint64_t tiles_recycled = 0;  // a tile's slot taken for other ground
};

// A square raster of the grid, row-major from its lower-left corner: 1 where the cell is free.
struct FreeSpaceRaster {
  Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();  // lower-left corner of cell (0, 0)
  double cell_size_m = 0.5;
  std::uint32_t cells_across = 0;
  std::span<const std::uint8_t> free;
};

class FreeSpaceGrid {
 public:
  void init(Arena& arena, const FreeSpaceConfig& config);
  [[nodiscard]] static std::size_t arena_bytes(const FreeSpaceConfig& config) noexcept;
  [[nodiscard]] bool enabled() const noexcept { return config_.tiles_across > 0; }

  // One beam, from the laser at from_m to its return at to_m (the ground plane's x, y).
  void add_beam(const Eigen::Vector2d& from_m, const Eigen::Vector2d& to_m) noexcept;

  // The free cells of the tiles_across x tiles_across tiles from the lowest tile held: the
  // ground the grid holds when it spans no more than that, else the part of it nearest the
  // last beam's origin. Written into the raster given at init (valid until the next call).
  [[nodiscard]] FreeSpaceRaster raster() noexcept;

  [[nodiscard]] const FreeSpaceCounters& counters() const noexcept { return counters_; }
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  struct Cell {
    std::uint8_t passes = 0;
    std::uint8_t returns = 0;
  };
  struct TileKey {
    std::int32_t x = 0;
    std::int32_t y = 0;
    bool held = false;
  };
  // The cells of tile (tile_x, tile_y), its slot taken for that ground if need be.
  Cell* tile_cells(std::int64_t tile_x, std::int64_t tile_y) noexcept;
  // The cell at whole cell coordinates (x, y).
  Cell& cell_at(std::int64_t x, std::int64_t y) noexcept;
  [[nodiscard]] bool is_free(const Cell& cell) const noexcept;

  FreeSpaceConfig config_;
  std::uint32_t cells_across_ = 0;
  std::span<Cell> cells_;  // tile slot after tile slot, each row-major
  std::span<TileKey> tiles_;
  std::span<std::uint8_t> raster_;
  Eigen::Vector2d last_origin_m_ = Eigen::Vector2d::Zero();
  FreeSpaceCounters counters_;
};

}  // namespace blockmap::map
