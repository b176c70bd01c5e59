// A building block the robot drove around, traced from where its level laser saw through
// (map::FreeSpaceGrid): the ground inside the robot's path that no beam crossed, bounded all
// round by ground that beams did cross. Its walls say where it is; this says where it ends
// where no wall was seen (behind trees, at a step of the block), and that the walls all round
// are one block. The paper's buildings are fitted from walls that meet at corners; a block of
// 100 m with steps on two sides and trees before a third has too few such corners.
//
//   find_blocks: the regions of cells not free, 4-connected, that do not reach the raster's
//   edge (ground seen round about) and are large enough ->
//   outline: in the block's frame (its walls' axis), the block's extent across at each metre
//   along, cut into bands of one extent each (a step is a new band), each band's sides moved
//   onto the walls seen along them -> a rectilinear polygon, counter-clockwise.
//
// Everything comes from an arena at init; nothing allocates afterwards.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include <Eigen/Core>

#include "blockmap/buildings/building.hpp"
#include "blockmap/buildings/buildings_config.hpp"
#include "blockmap/core/arena.hpp"
#include "blockmap/map/free_space_grid.hpp"

namespace blockmap::buildings {

// A wall seen along a block's side, in the block's frame (u along its axis, v across).
struct SideWall {
  int axis = 0;        // 0: runs along u, at v = level; 1: runs along v, at u = level
  double level = 0.0;  // the across coordinate
  double lo = 0.0;     // its interval along its axis
  double hi = 0.0;
};

class BlockTracer {
 public:
  // At most four bands: 16 corners.
  static constexpr std::size_t kMaxBands = kMaxFootprintVertices / 4;

  struct Block {
    std::uint16_t label = 0;
    std::uint32_t first_cell = 0;  // its cells: cells()[first_cell, first_cell + cell_count)
    std::uint32_t cell_count = 0;
  };
  struct Outline {
    std::array<Eigen::Vector2d, kMaxFootprintVertices> corners{};  // in the block's frame
    std::uint8_t size = 0;
  };

  // Room for rasters of up to max_cells cells.
  void init(Arena& arena, const BuildingsConfig& config, std::size_t max_cells);
  [[nodiscard]] static std::size_t arena_bytes(const BuildingsConfig& config,
                                               std::size_t max_cells) noexcept;
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

  // The blocks of this raster (valid until the next call).
  std::span<const Block> find_blocks(const map::FreeSpaceRaster& raster) noexcept;
  // Whether p_m is in a free cell of the last find_blocks()' raster.
  [[nodiscard]] bool is_free(const Eigen::Vector2d& p_m) const noexcept;
  // Whether a cell of the block lies within reach_m of p_m.
  [[nodiscard]] bool reaches(const Block& block, const Eigen::Vector2d& p_m,
                             double reach_m) const noexcept;
  // The axis of the block's frame: axis_rad, or turned by 90 degrees, so that u runs along its
  // longer side (its bands are cut across that).
  [[nodiscard]] double long_axis(const Block& block, double axis_rad) const noexcept;
  // The block's outline in the frame turned by axis_rad (a long_axis()), its sides on the
  // walls given; size 0 when it has no extent.
  [[nodiscard]] Outline outline(const Block& block, double axis_rad,
                                std::span<const SideWall> walls) noexcept;

 private:
  struct Band {
    double u0 = 0.0;
    double u1 = 0.0;
    double v_lo = 0.0;
    double v_hi = 0.0;
  };
  [[nodiscard]] Eigen::Vector2d cell_centre(std::uint32_t cell) const noexcept;
  // Each column's extent across (column_lo_, column_hi_), median-filtered; the column count.
  std::size_t measure_columns(const Block& block, double axis_rad, double& u_start) noexcept;
  std::size_t cut_bands(std::size_t columns, double u_start) noexcept;
  void join_bands(std::size_t a) noexcept;
  // Sides of neighbouring bands within kSameSideM are one side; bands alike on both are one.
  void merge_alike_bands() noexcept;
  void snap_to_walls(std::span<const SideWall> walls) noexcept;

  BuildingsConfig config_;
  map::FreeSpaceRaster raster_;
  std::span<std::uint16_t> labels_;  // 0: free or not yet reached
  std::span<std::uint32_t> cells_;   // each block's cells, block after block
  std::span<Block> blocks_;
  std::size_t block_count_ = 0;
  std::span<double> column_lo_;
  std::span<double> column_hi_;
  std::span<double> scratch_;
  std::array<Band, kMaxBands * 4> bands_{};
  std::size_t band_count_ = 0;
};

}  // namespace blockmap::buildings
