// Every parameter of building fitting, with defaults for a city block mapped with GPS-grade
// poses (walls bent by up to ~2 m, the paper's Ft. Benning figure). Units are in the names.
#pragma once

#include <cstddef>
#include <string>

namespace blockmap::buildings {

struct BuildingsConfig {
  // A wall plane becomes a footprint segment when it is at least this long.
  double min_wall_length_m = 2.0;
  // Vertical planes the detector left "other" because they are low (a level laser's trace on
  // a wall it saw only from afar or at a slant) may join a building that has a wall; they
  // never make one on their own (cars, kerbs and fences are such planes too).
  bool use_low_walls = true;
  // A low plane's ends count (a notch, an edge in view) only when it was seen this densely
  // (points per metre of its length): a level laser's trace seen from close by, not from afar
  // through a hedge.
  double min_low_wall_support_per_m = 1000.0;

  // Two near-perpendicular walls are corners of one building when the corner where their
  // lines meet is within corner_gap_m of both (occlusion and pose errors leave gaps there).
  double corner_gap_m = 3.0;
  double corner_angle_tolerance_deg = 20.0;
  // Two near-parallel walls are pieces of one wall, broken by a tree or a car, when they are
  // at most collinear_offset_m apart across and max_occlusion_gap_m along.
  double collinear_angle_tolerance_deg = 10.0;
  double collinear_offset_m = 1.0;
  double max_occlusion_gap_m = 10.0;

  // Overlapping parallel walls closer than this are one wall seen on two passes with
  // different pose errors (GPS-grade poses put them a metre or two apart).
  double parallel_merge_offset_m = 2.0;

  // A model's edge explains an observed wall within fit_tolerance_m of it.
  double fit_tolerance_m = 2.0;
  // A notch of an L or T is at least this deep and wide.
  double min_notch_m = 2.0;
  // The model choice: cost = 2 x observed length no edge explains + length of edges in line
  // with an observed wall but not seen + mean distance term + this penalty (metres of wall),
  // so that a more complex model must explain several metres more than the simpler one.
  double l_penalty_m = 3.0;
  double t_penalty_m = 6.0;
  // Gaps shorter than this in an observed wall are closed; longer ones become virtual walls.
  double min_virtual_gap_m = 0.5;
  // A model is kept when it explains at least this share of the observed wall length;
  // otherwise the building stays "unknown" rather than invented.
  double min_explained_share = 0.7;

  // Blocks the robot drove around, traced from where its level laser saw through
  // (BlockTracer; the mapper's [free_space] grid): a region no beam crossed, ringed by ground
  // that beams did cross, of at least min_block_area_m2, with at least min_block_wall_m of
  // walls within block_wall_reach_m of it. Its outline is measured every block_column_m
  // along it; a change of its extent across by more than block_step_m starts a new band
  // (bands narrower than block_min_band_m join a neighbour), and a band's side moves onto
  // walls seen within block_snap_m of it. The block replaces the buildings fitted inside it.
  double min_block_area_m2 = 400.0;
  double min_block_wall_m = 20.0;
  double block_wall_reach_m = 2.0;
  double block_column_m = 1.0;
  double block_step_m = 3.0;
  double block_min_band_m = 6.0;
  double block_snap_m = 3.0;

  // Capacities, taken from the arena at init.
  std::size_t max_walls = 1024;     // wall segments per fit
  std::size_t max_buildings = 128;  // buildings per fit
  std::size_t max_blocks = 8;       // traced blocks per fit
};

// Empty when the configuration is usable, otherwise the first problem, naming the key.
[[nodiscard]] std::string validate(const BuildingsConfig& config);

}  // namespace blockmap::buildings
