// The map stages' tables: [window], [projection], [free_space] and [registry].
#include <cstdint>
#include <string>

#include "config_tables.hpp"
#include "toml_reader.hpp"

namespace blockmap::hal::config {

void read_window_table(TableReader& t, double voxel_size_m, map::VoxelWindowConfig& c) {
  c.tile_size_m = t.positive_or("tile_size_m", c.tile_size_m);
  const std::int64_t tiles = t.integer_or("tiles_across", c.tiles_across);
  if (tiles < 3 || tiles > 255 || tiles % 2 == 0) {
    t.fail("tiles_across", "must be odd, from 3 to 255 (the robot's tile is the middle one)");
  }
  c.tiles_across = static_cast<std::uint32_t>(tiles);
  c.max_samples = t.capacity_or("max_samples", c.max_samples);
  const std::int64_t core = t.integer_or("core_tiles_across", c.core_tiles_across);
  if (core < 0 || core > tiles || (core != 0 && core % 2 == 0)) {
    t.fail("core_tiles_across", "must be 0 (every tile) or odd and at most tiles_across");
  }
  c.core_tiles_across = static_cast<std::uint32_t>(core);
  c.reserve_samples = t.capacity_or("reserve_samples", c.reserve_samples);
  t.finish();
  // The tile must hold whole 4-voxel blocks of the detector's samples ([planes] sample_size_m).
  map::VoxelWindowConfig window = c;
  window.voxel_size_m = voxel_size_m;
  if (const std::string problem = map::validate(window); !problem.empty()) {
    t.reject(problem);
  }
}

void read_projection_table(TableReader& t, map::ScanProjectorConfig& c) {
  c.min_range_m = t.non_negative_or("min_range_m", c.min_range_m);
  c.max_range_m = t.positive_or("max_range_m", c.max_range_m);
  if (!(c.max_range_m > c.min_range_m)) {
    t.fail("max_range_m", "must be more than min_range_m");
  }
  c.far_ground_range_m = t.non_negative_or("far_ground_range_m", c.far_ground_range_m);
  c.ground_band_m = t.non_negative_or("ground_band_m", c.ground_band_m);
  t.finish();
}

void read_free_space_table(TableReader& t, map::FreeSpaceConfig& c) {
  // Where the level lasers saw through: blocks the robot drove around are traced in it.
  const std::int64_t tiles = t.integer_or("tiles_across", c.tiles_across);
  if (tiles < 0 || tiles > 64) {
    t.fail("tiles_across", "must be from 0 (off) to 64 (tiles of 32 cells)");
  }
  c.tiles_across = static_cast<std::uint32_t>(tiles);
  c.cell_size_m = t.positive_or("cell_size_m", c.cell_size_m);
  c.stop_short_m = t.non_negative_or("stop_short_m", c.stop_short_m);
  t.finish();
  if (const std::string problem = map::validate(c); !problem.empty()) {
    t.reject(problem);
  }
}

void read_registry_table(TableReader& t, map::PlaneRegistryConfig& c) {
  // The plane registry's capacities (docs/mapper.md, Memory): the planes in the window, and
  // those that left it, which a long mission over new ground fills.
  c.max_live_planes = t.capacity_or("max_live_planes", c.max_live_planes);
  c.max_final_planes = t.capacity_or("max_final_planes", c.max_final_planes);
  t.finish();
  if (const std::string problem = map::validate(c); !problem.empty()) {
    t.reject(problem);
  }
}

}  // namespace blockmap::hal::config
