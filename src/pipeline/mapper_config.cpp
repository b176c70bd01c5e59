#include "blockmap/pipeline/mapper_config.hpp"

#include <algorithm>
#include <cmath>

#include "blockmap/core/angles.hpp"

namespace blockmap::pipeline {
namespace {

// The detector's blocks for a window of max_samples: a quarter of them (a city's window fills
// a block with 6-9 samples), but a block per sample up to 4,096 (a small window's samples are
// scattered).
std::size_t window_blocks(std::size_t max_samples) noexcept {
  constexpr std::size_t kSmallWindowBlocks = 4096;
  return std::max(max_samples / 6, std::min(max_samples, kSmallWindowBlocks));
}

}  // namespace

// Whether every laser scans a level plane (within scan_plane_angle_deg): its scan plane's
// normal is the mount's z axis, whose vertical part is cos(roll) cos(pitch).
bool is_level_laser(const MapperConfig& config, std::size_t laser) noexcept {
  const double cos_level = std::cos(radians_from_degrees(config.scan_plane_angle_deg));
  const map::SensorMount& mount = config.laser_mounts[laser];
  return std::abs(std::cos(mount.roll_rad) * std::cos(mount.pitch_rad)) >= cos_level;
}

bool only_level_lasers(const MapperConfig& config) noexcept {
  for (std::size_t laser = 0; laser < config.laser_count; ++laser) {
    if (!is_level_laser(config, laser)) {
      return false;
    }
  }
  return config.laser_count > 0;
}

std::size_t free_space_cells(const MapperConfig& config) noexcept {
  const std::size_t across =
      std::size_t{config.free_space.tiles_across} * map::FreeSpaceConfig::kCellsPerTile;
  return config.fit_buildings ? across * across : 0;
}

// The window's voxels are the detector's samples: it hands them over as they are.
map::VoxelWindowConfig window_config(const MapperConfig& config) noexcept {
  map::VoxelWindowConfig window = config.window;
  window.voxel_size_m = config.planes.sample_size_m;
  return window;
}

// The detector's configuration inside the mapper: it holds what the window holds. With level
// lasers only, a wall is a line in the map: the vertical plane through it.
planes::PlanesConfig detector_config(const MapperConfig& config) noexcept {
  planes::PlanesConfig planes = config.planes;
  planes.walls_from_lines = planes.walls_from_lines || only_level_lasers(config);
  planes.max_samples = config.window.max_samples;
  planes.max_blocks =
      planes.max_blocks == 0 ? window_blocks(planes.max_samples) : planes.max_blocks;
  planes.keep_shapes = config.incremental_extraction;
  return planes;
}

// Scans are matched only when drawn with the localizer's poses as they come: given poses (a
// survey's, the simulation's) are what the map should be drawn with, and the smoothed path of
// a pose lag already has the headings that matching gives the live poses (docs/localize.md,
// Scan matching).
namespace {

bool scans_matched(const MapperConfig& config) noexcept {
  return config.scan_matching.enabled && config.pose_source == PoseSource::kLocalizer &&
         !(config.localizer.map_pose_lag_s > 0.0);
}

}  // namespace

localize::ScanMatchConfig matcher_config(const MapperConfig& config) noexcept {
  localize::ScanMatchConfig matching = config.scan_matching;
  matching.enabled = scans_matched(config);
  // The rigid path places the matcher's frame: laid onto the filter's path as the run goes,
  // the frame would turn while a wall is seen, and bend it.
  if (solves_the_path(config)) {
    matching.anchor_time_s = 0.0;
  }
  return matching;
}

localize::PathSmootherConfig path_config(const MapperConfig& config) noexcept {
  localize::PathSmootherConfig path = config.path;
  // Until the matcher has matched a scan, the turn the odometry carries alone holds the
  // gyroscope's bias as the filter starts with it (docs/localize.md, The gyroscope's bias
  // before a scan is matched).
  path.unlearnt_yaw_rate_bias_sigma_radps =
      config.localizer.filter.initial_yaw_rate_bias_sigma_radps;
  return path;
}

map::PlaneRegistryConfig registry_config(const MapperConfig& config) noexcept {
  map::PlaneRegistryConfig registry = config.registry;
  registry.max_detected_planes = config.planes.max_planes;
  registry.walls_from_lines = detector_config(config).walls_from_lines;
  registry.line_width_m = 0.5 * config.planes.sample_size_m;
  return registry;
}

// Whether `config` has the mapper solve the whole run's path. Not by default with the
// free-space grid: it keeps what the beams carved with the poses of their time, and walls
// moved off it would no longer be the outline traced in it.
bool solves_the_path(const MapperConfig& config) noexcept {
  return config.rigid_path == RigidPath::kOn ||
         (config.rigid_path == RigidPath::kWhereScansAreMatched && scans_matched(config) &&
          config.free_space.tiles_across == 0);
}

std::size_t scan_queue_slots(const MapperConfig& config) noexcept {
  const double lag_s =
      config.pose_source == PoseSource::kLocalizer ? config.localizer.map_pose_lag_s : 0.0;
  if (!(lag_s > 0.0) || !(config.scans_per_s > 0.0)) {
    return config.scan_queue_capacity;
  }
  const double held_s = lag_s + config.reorder_window_s + 1.0;
  return std::max(config.scan_queue_capacity,
                  static_cast<std::size_t>(std::ceil(held_s * config.scans_per_s)));
}

namespace {

// Each stage's own checks, on what it is configured with.
std::string validate_stages(const MapperConfig& config) {
  if (std::string problem = localize::validate(config.localizer); !problem.empty()) {
    return problem;
  }
  if (std::string problem = localize::validate(config.scan_matching); !problem.empty()) {
    return problem;
  }
  if (std::string problem = map::validate(window_config(config)); !problem.empty()) {
    return problem;
  }
  if (std::string problem = planes::validate(detector_config(config)); !problem.empty()) {
    return problem;
  }
  if (std::string problem = map::validate(registry_config(config)); !problem.empty()) {
    return problem;
  }
  if (std::string problem = buildings::validate(config.buildings); !problem.empty()) {
    return "buildings: " + problem;
  }
  if (std::string problem = map::validate(config.free_space); !problem.empty()) {
    return problem;
  }
  return {};
}

// What the whole run's path needs of the rest.
std::string validate_rigid_path(const MapperConfig& config) {
  if (!solves_the_path(config)) {
    return config.prior_map.enabled ? "mapper: prior_map needs the rigid path (rigid_path on, "
                                      "scan matching with the localizer's live poses)"
                                    : std::string();
  }
  if (std::string problem = localize::validate(config.path); !problem.empty()) {
    return problem;
  }
  if (std::string problem = localize::validate(config.loop_closure); !problem.empty()) {
    return problem;
  }
  if (std::string problem = localize::validate(config.prior_map); !problem.empty()) {
    return problem;
  }
  if (!matcher_config(config).enabled) {
    return "mapper: rigid_path needs scan matching with the localizer's live poses "
           "([scan_matching] enabled, no pose lag)";
  }
  if (!(config.rigid_view_change_m > 0.0)) {
    return "mapper: rigid_path view_change_m must be positive";
  }
  if (config.free_space.tiles_across > 0) {
    return "mapper: rigid_path would move the walls off the free-space grid, which stays "
           "where the scans were drawn ([free_space] tiles_across = 0, or rigid_path off)";
  }
  return {};
}

// The mapper's own keys.
std::string validate_mapper(const MapperConfig& config) {
  if (config.laser_count > kMaxLasers) {
    return "mapper: at most 4 lasers";
  }
  if (!(config.scan_plane_angle_deg >= 0.0 && config.scan_plane_angle_deg < 90.0) ||
      !(config.scan_plane_distance_m >= 0.0) || !(config.scan_plane_spacing_m > 0.0)) {
    return "mapper: scan_plane_angle_deg must be in [0, 90), the scan plane distances >= 0";
  }
  if (!(config.extract_every_s > 0.0) || !(config.reorder_window_s >= 0.0)) {
    return "mapper: extract_every_s must be positive and reorder_window_s not negative";
  }
  if (config.max_beams < 1 || config.max_beams > msg::kMaxLaserBeams ||
      !(config.scans_per_s >= 0.0)) {
    return "mapper: max_beams must be 1 to 1141 and scans_per_s not negative";
  }
  if (config.reorder_capacity < 1 || config.scan_queue_capacity < 1 ||
      (config.pose_source == PoseSource::kExternal && config.max_external_poses < 2)) {
    return "mapper: the reorder buffer and the scan queue need room (and 2 external poses)";
  }
  if (!(config.projection.min_range_m >= 0.0) ||
      !(config.projection.max_range_m > config.projection.min_range_m)) {
    return "mapper: projection ranges must satisfy 0 <= min_range_m < max_range_m";
  }
  if (!(config.projection.far_ground_range_m >= 0.0) || !(config.projection.ground_band_m >= 0.0) ||
      !std::isfinite(config.projection.axle_height_m)) {
    return "mapper: far_ground_range_m and ground_band_m must not be negative, axle_height_m "
           "finite";
  }
  return {};
}

}  // namespace

std::string validate(const MapperConfig& config) {
  for (const auto check : {validate_stages, validate_rigid_path, validate_mapper}) {
    if (std::string problem = check(config); !problem.empty()) {
      return problem;
    }
  }
  return {};
}

}  // namespace blockmap::pipeline
