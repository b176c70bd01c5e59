// The mapper's configuration: every stage's table with the mapper's defaults, and the values
// each stage's own configuration is derived from it with (one way: a user's setting is never
// rewritten; what follows from it is computed here).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

#include "blockmap/buildings/buildings_config.hpp"
#include "blockmap/localize/localizer.hpp"
#include "blockmap/localize/loop_closer.hpp"
#include "blockmap/localize/path_smoother.hpp"
#include "blockmap/localize/prior_map.hpp"
#include "blockmap/localize/scan_matcher.hpp"
#include "blockmap/map/free_space_grid.hpp"
#include "blockmap/map/plane_registry.hpp"
#include "blockmap/map/scan_projector.hpp"
#include "blockmap/map/voxel_window.hpp"
#include "blockmap/msg/laser_scan.hpp"
#include "blockmap/pipeline/lasers.hpp"
#include "blockmap/pipeline/scan_poses.hpp"
#include "blockmap/planes/planes_config.hpp"

namespace blockmap::pipeline {

// The detector's defaults for a window: 6-9 samples per occupied block on the simulated
// worlds, so a sixth of the window's samples in blocks holds even a full window of the
// sparsest. max_blocks = 0 here means that sixth (detector_config), so that a larger window
// gets the blocks to hold it.
// The corner look is off: in the streamed maps it found nothing more, at a cost in time
// (docs/mapper.md; [planes] corner_look = true turns it on).
[[nodiscard]] inline planes::PlanesConfig window_planes_config() noexcept {
  planes::PlanesConfig config;
  config.max_blocks = 0;
  config.corner_look = false;
  config.max_patches = 8192;
  config.max_planes = 512;
  return config;
}

// The localizer's defaults for the mapper: 2,000 particles (half the batch default) keep the
// whole pipeline inside 64 MiB; the smoothing window stays one minute.
[[nodiscard]] inline localize::LocalizerConfig mapper_localizer_config() noexcept {
  localize::LocalizerConfig config;
  config.filter.particle_count = 2000;
  return config;
}

[[nodiscard]] inline buildings::BuildingsConfig mapper_buildings_config() noexcept {
  buildings::BuildingsConfig config;
  config.max_walls = 512;
  config.max_buildings = 64;
  return config;
}

// When the mapper solves the whole run's path (MapperConfig::rigid_path).
enum class RigidPath : std::uint8_t {
  kOff,
  kWhereScansAreMatched,  // the default: scans matched and no free-space grid
  kOn  // asked for: a config with no scans to match or with a free-space grid is refused
};

// The path smoother as the mapper runs it. Its odometry is the scan matcher's matched poses,
// whose heading wanders more per metre than the calibrated wheels and gyroscope that the
// smoother's own defaults describe: a matcher against its own sliding map carries a heading
// error on, and starts a new frame when the filter's pose snaps: twice the smoother's own
// heading noise per root metre gives the solved path a truer shape (docs/localize.md, In the
// mapper).
[[nodiscard]] inline localize::PathSmootherConfig path_for_matched_scans() noexcept {
  localize::PathSmootherConfig config;
  config.yaw_sigma_per_sqrt_m = 0.004;
  config.matched_yaw_sigma_per_sqrt_m = 0.001;
  config.matched_across_sigma_per_sqrt_m = 0.005;
  return config;
}

struct MapperConfig {
  localize::LocalizerConfig localizer = mapper_localizer_config();
  PoseSource pose_source = PoseSource::kLocalizer;
  // With the localizer's poses: each level laser's scan matched against the grid of what the
  // scans before it hit, and every scan drawn with the corrected pose (localize::ScanMatcher,
  // docs/localize.md).
  localize::ScanMatchConfig scan_matching;
  // The whole run's path at once (localize::PathSmoother, docs/localize.md): the level
  // lasers' matched poses as its odometry and every fix the localizer took. At the end of the
  // run every final plane is moved by how far the solved path lies from the poses it was
  // drawn with while the robot was near it and saw it, and the buildings are fitted again.
  // Needs scan matching (the localizer's live poses) and no free-space grid (it is not
  // moved); on by default wherever those hold.
  RigidPath rigid_path = RigidPath::kWhereScansAreMatched;
  localize::PathSmootherConfig path = path_for_matched_scans();
  // With the rigid path: revisits found by matching submaps of the level scans against the
  // earlier ones near them, each a constraint on the path (localize::LoopCloser).
  localize::LoopClosureConfig loop_closure;
  // With the rigid path: Monte Carlo localization against a prior 2D map (its walls given to
  // Mapper::set_prior_map() at start-up), whose placings hold the path beside or instead of
  // the receiver's fixes (localize::MapLocalizer). Off unless a map is given.
  localize::PriorMapConfig prior_map;
  // With the rigid path, the stream shows each plane where the latest solve puts it (every
  // 10 s of scan time; docs/localize.md, The rigid map as it goes), and the buildings are
  // fitted to the planes so: a plane is reported again when that moves it more than
  // rigid_view_change_m at any vertex. Off: as drawn until the end's move.
  bool rigid_view = true;
  double rigid_view_change_m = 0.05;
  // After the end's move, final planes it laid on one surface become one
  // (PlaneRegistry::join_finals_on_one_surface). Off: each stays as it was finalized.
  bool rigid_join_finals = true;
  std::size_t max_external_poses = 1024;  // kExternal: the newest poses kept to interpolate

  std::array<map::SensorMount, kMaxLasers> laser_mounts{};
  std::size_t laser_count = 0;
  map::ScanProjectorConfig projection;
  map::VoxelWindowConfig window;  // its voxel_size_m is the detector's sample_size_m (below)
  // The detector runs over the window: its sample capacity is the window's (init() sets it),
  // and a window holds fewer planes and section planes than a whole city's cloud.
  planes::PlanesConfig planes = window_planes_config();
  map::PlaneRegistryConfig registry;

  double extract_every_s = 1.0;  // of scan time, between plane extractions
  // Between two extractions with no tile leaving the window, the detector keeps its samples
  // and shapes and takes only the samples that gained points (a few per cent of the window a
  // second); shapes are estimated again only around them. The planes are the same either way
  // (MapperSim.TheSameRunGivesTheSameStreamWithOrWithoutKeptShapes); false detects every
  // window afresh.
  bool incremental_extraction = true;
  // A detected plane within this angle of a laser's scan plane that passes this close to
  // where the laser has been, while moving within that plane, is that scan plane
  // (planes::PlaneExclusion): not reported. The positions are kept every
  // scan_plane_spacing_m of its path (the last kScanPlanePath). A real surface there (a car's
  // bonnet at the height of a level laser) is lost with it.
  double scan_plane_angle_deg = 10.0;
  double scan_plane_distance_m = 0.5;
  double scan_plane_spacing_m = 0.5;
  // Buildings from the map's walls (seed, section IV), fitted again after every extraction:
  // the estimate improves as data arrives. Capacities for one window's city block.
  bool fit_buildings = true;
  buildings::BuildingsConfig buildings = mapper_buildings_config();
  // Where the level lasers saw through (map::FreeSpaceGrid), for tracing the blocks the robot
  // drove around (buildings::BlockTracer). Off by default (tiles_across 0): it costs a grid
  // walk per beam, and a robot that maps a street rather than drives round blocks gains
  // nothing from it.
  map::FreeSpaceConfig free_space;
  double reorder_window_s = 0.25;  // a message this much older than the newest is released
  std::size_t reorder_capacity = 512;
  std::size_t scan_queue_capacity = 128;  // scans wait for the reorder window and the poses
  // The most beams a scan of these lasers has (a queued scan keeps room for this many), and
  // all lasers' scans per second together: with a pose lag (localizer.map_pose_lag_s) the
  // queue grows to hold the lag's scans (scan_queue_slots()). 0: not known, no growth.
  std::size_t max_beams = msg::kMaxLaserBeams;
  double scans_per_s = 0.0;
};

// The scans the queue holds: scan_queue_capacity, or the lag, the reorder window and a second
// more of scans at scans_per_s when that is more.
[[nodiscard]] std::size_t scan_queue_slots(const MapperConfig& config) noexcept;

// Empty when usable, otherwise what is wrong.
[[nodiscard]] std::string validate(const MapperConfig& config);

// What each stage is configured with, derived from the mapper's configuration.
[[nodiscard]] bool is_level_laser(const MapperConfig& config, std::size_t laser) noexcept;
[[nodiscard]] bool only_level_lasers(const MapperConfig& config) noexcept;
[[nodiscard]] std::size_t free_space_cells(const MapperConfig& config) noexcept;
[[nodiscard]] map::VoxelWindowConfig window_config(const MapperConfig& config) noexcept;
[[nodiscard]] planes::PlanesConfig detector_config(const MapperConfig& config) noexcept;
[[nodiscard]] localize::ScanMatchConfig matcher_config(const MapperConfig& config) noexcept;
[[nodiscard]] localize::PathSmootherConfig path_config(const MapperConfig& config) noexcept;
[[nodiscard]] map::PlaneRegistryConfig registry_config(const MapperConfig& config) noexcept;
[[nodiscard]] bool solves_the_path(const MapperConfig& config) noexcept;

}  // namespace blockmap::pipeline
