#include "blockmap/map/free_space_grid.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "blockmap/core/check.hpp"
#include "blockmap/core/floor_div.hpp"

namespace blockmap::map {
namespace {

constexpr std::int64_t kTileCells = FreeSpaceConfig::kCellsPerTile;
constexpr std::size_t kSlack = 64;  // alignment of each array

}  // namespace

std::string validate(const FreeSpaceConfig& config) {
  if (config.tiles_across > 64) {
    return "free_space: tiles_across must be from 0 (off) to 64";
  }
  if (!(config.cell_size_m >= 0.05 && config.cell_size_m <= 5.0)) {
    return "free_space: cell_size_m must be from 0.05 to 5";
  }
  if (!(config.stop_short_m >= 0.0) || !(config.free_pass_ratio >= 1.0) || config.min_passes == 0) {
    return "free_space: stop_short_m must be >= 0, free_pass_ratio >= 1 and min_passes >= 1";
  }
  return {};
}

void FreeSpaceGrid::init(Arena& arena, const FreeSpaceConfig& config) {
  const std::string problem = validate(config);
  BLOCKMAP_CHECK_MSG(problem.empty(), "an invalid free-space configuration reached init()");
  config_ = config;
  counters_ = {};
  cells_across_ = config.tiles_across * FreeSpaceConfig::kCellsPerTile;
  if (!enabled()) {
    return;
  }
  const std::size_t cell_count = std::size_t{cells_across_} * cells_across_;
  cells_ = arena.allocate_array<Cell>(cell_count, "free_space.cells");
  tiles_ = arena.allocate_array<TileKey>(std::size_t{config.tiles_across} * config.tiles_across,
                                         "free_space.tiles");
  raster_ = arena.allocate_array<std::uint8_t>(cell_count, "free_space.raster");
  std::fill(cells_.begin(), cells_.end(), Cell{});
  std::fill(tiles_.begin(), tiles_.end(), TileKey{});
}

std::size_t FreeSpaceGrid::arena_bytes(const FreeSpaceConfig& config) noexcept {
  if (config.tiles_across == 0) {
    return 0;
  }
  const std::size_t tiles = std::size_t{config.tiles_across} * config.tiles_across;
  const std::size_t cells = tiles * FreeSpaceConfig::kCellsPerTile * FreeSpaceConfig::kCellsPerTile;
  return cells * (sizeof(Cell) + sizeof(std::uint8_t)) + tiles * sizeof(TileKey) + 3 * kSlack;
}

std::size_t FreeSpaceGrid::memory_bytes() const noexcept {
  return sizeof(*this) + cells_.size_bytes() + tiles_.size_bytes() + raster_.size_bytes();
}

FreeSpaceGrid::Cell* FreeSpaceGrid::tile_cells(std::int64_t tile_x, std::int64_t tile_y) noexcept {
  const auto across = static_cast<std::int64_t>(config_.tiles_across);
  const auto slot =
      static_cast<std::size_t>(floor_mod(tile_y, across) * across + floor_mod(tile_x, across));
  TileKey& key = tiles_[slot];
  Cell* const cells = cells_.data() + slot * kTileCells * kTileCells;
  if (!key.held || key.x != tile_x || key.y != tile_y) {
    // Other ground wants this slot: what the tile held of the old ground is forgotten.
    counters_.tiles_recycled += key.held ? 1 : 0;
    std::fill_n(cells, kTileCells * kTileCells, Cell{});
    key = {static_cast<std::int32_t>(tile_x), static_cast<std::int32_t>(tile_y), true};
  }
  return cells;
}

FreeSpaceGrid::Cell& FreeSpaceGrid::cell_at(std::int64_t x, std::int64_t y) noexcept {
  const std::int64_t tile_x = floor_div(x, kTileCells);
  const std::int64_t tile_y = floor_div(y, kTileCells);
  return tile_cells(tile_x,
                    tile_y)[(y - tile_y * kTileCells) * kTileCells + (x - tile_x * kTileCells)];
}

void FreeSpaceGrid::add_beam(const Eigen::Vector2d& from_m, const Eigen::Vector2d& to_m) noexcept {
  if (!enabled() || !from_m.allFinite() || !to_m.allFinite()) {
    return;
  }
  ++counters_.beams;
  last_origin_m_ = from_m;
  const double inverse_cell = 1.0 / config_.cell_size_m;
  const Eigen::Vector2d delta_m = to_m - from_m;
  const double length_m = delta_m.norm();
  // The return's own cell.
  Cell& end = cell_at(static_cast<std::int64_t>(std::floor(to_m.x() * inverse_cell)),
                      static_cast<std::int64_t>(std::floor(to_m.y() * inverse_cell)));
  end.returns = static_cast<std::uint8_t>(std::min<int>(end.returns + 1, 255));
  const double carve_m = length_m - config_.stop_short_m;
  if (carve_m <= 0.0) {
    return;
  }
  // The cells the beam crosses up to carve_m, one after the other (a grid walk: each step
  // goes to the cell whose border the beam meets first).
  const Eigen::Vector2d direction = delta_m / length_m;
  const Eigen::Vector2d start = from_m * inverse_cell;
  auto x = static_cast<std::int64_t>(std::floor(start.x()));
  auto y = static_cast<std::int64_t>(std::floor(start.y()));
  const std::int64_t step_x = direction.x() >= 0.0 ? 1 : -1;
  const std::int64_t step_y = direction.y() >= 0.0 ? 1 : -1;
  constexpr double kNever = std::numeric_limits<double>::infinity();
  // Distance along the beam (in cells) between two vertical / horizontal borders, and to the
  // first of each.
  const double delta_x = direction.x() != 0.0 ? std::abs(1.0 / direction.x()) : kNever;
  const double delta_y = direction.y() != 0.0 ? std::abs(1.0 / direction.y()) : kNever;
  const auto first_border = [](double at, std::int64_t cell, std::int64_t step, double delta) {
    const double border = step > 0 ? static_cast<double>(cell + 1) : static_cast<double>(cell);
    return delta == kNever ? kNever : std::abs(border - at) * delta;
  };
  double next_x = first_border(start.x(), x, step_x, delta_x);
  double next_y = first_border(start.y(), y, step_y, delta_y);
  const double carve_cells = carve_m * inverse_cell;
  double reached = 0.0;
  // The tile being crossed, looked up again only when the walk leaves it.
  std::int64_t tile_x = floor_div(x, kTileCells);
  std::int64_t tile_y = floor_div(y, kTileCells);
  Cell* tile = tile_cells(tile_x, tile_y);
  while (reached < carve_cells) {
    if (x - tile_x * kTileCells < 0 || x - tile_x * kTileCells >= kTileCells ||
        y - tile_y * kTileCells < 0 || y - tile_y * kTileCells >= kTileCells) {
      tile_x = floor_div(x, kTileCells);
      tile_y = floor_div(y, kTileCells);
      tile = tile_cells(tile_x, tile_y);
    }
    Cell& cell = tile[(y - tile_y * kTileCells) * kTileCells + (x - tile_x * kTileCells)];
    cell.passes = static_cast<std::uint8_t>(std::min<int>(cell.passes + 1, 255));
    ++counters_.cells_crossed;
    if (next_x < next_y) {
      reached = next_x;
      next_x += delta_x;
      x += step_x;
    } else {
      reached = next_y;
      next_y += delta_y;
      y += step_y;
    }
  }
}

bool FreeSpaceGrid::is_free(const Cell& cell) const noexcept {
  return cell.passes >= config_.min_passes &&
         static_cast<double>(cell.passes) >= config_.free_pass_ratio * cell.returns;
}

FreeSpaceRaster FreeSpaceGrid::raster() noexcept {
  FreeSpaceRaster out;
  out.cell_size_m = config_.cell_size_m;
  out.cells_across = cells_across_;
  if (!enabled()) {
    return out;
  }
  // The lowest tile held in each axis; when the held tiles span more than the ring, the ring
  // around the last beam's origin.
  const auto across = static_cast<std::int64_t>(config_.tiles_across);
  std::int64_t low_x = std::numeric_limits<std::int64_t>::max();
  std::int64_t low_y = low_x;
  std::int64_t high_x = std::numeric_limits<std::int64_t>::min();
  std::int64_t high_y = high_x;
  for (const TileKey& key : tiles_) {
    if (key.held) {
      low_x = std::min<std::int64_t>(low_x, key.x);
      low_y = std::min<std::int64_t>(low_y, key.y);
      high_x = std::max<std::int64_t>(high_x, key.x);
      high_y = std::max<std::int64_t>(high_y, key.y);
    }
  }
  const double tile_m = config_.cell_size_m * FreeSpaceConfig::kCellsPerTile;
  const auto robot_x = static_cast<std::int64_t>(std::floor(last_origin_m_.x() / tile_m));
  const auto robot_y = static_cast<std::int64_t>(std::floor(last_origin_m_.y() / tile_m));
  if (low_x > high_x || high_x - low_x >= across) {
    low_x = robot_x - across / 2;
  }
  if (low_y > high_y || high_y - low_y >= across) {
    low_y = robot_y - across / 2;
  }
  out.origin_m =
      Eigen::Vector2d(static_cast<double>(low_x) * tile_m, static_cast<double>(low_y) * tile_m);
  std::fill(raster_.begin(), raster_.end(), std::uint8_t{0});
  for (std::int64_t tile_y = low_y; tile_y < low_y + across; ++tile_y) {
    for (std::int64_t tile_x = low_x; tile_x < low_x + across; ++tile_x) {
      const auto slot =
          static_cast<std::size_t>(floor_mod(tile_y, across) * across + floor_mod(tile_x, across));
      const TileKey& key = tiles_[slot];
      if (!key.held || key.x != tile_x || key.y != tile_y) {
        continue;  // never seen, or forgotten: not free
      }
      const Cell* const cells = cells_.data() + slot * kTileCells * kTileCells;
      for (std::int64_t in_y = 0; in_y < kTileCells; ++in_y) {
        const std::int64_t row = (tile_y - low_y) * kTileCells + in_y;
        std::uint8_t* const out_row =
            raster_.data() + row * cells_across_ + (tile_x - low_x) * kTileCells;
        for (std::int64_t in_x = 0; in_x < kTileCells; ++in_x) {
          out_row[in_x] = is_free(cells[in_y * kTileCells + in_x]) ? 1 : 0;
        }
      }
    }
  }
  out.free = raster_;
  return out;
}

}  // namespace blockmap::map
