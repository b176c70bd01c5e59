#include "blockmap/pipeline/mapper.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include <Eigen/Geometry>

#include "blockmap/core/check.hpp"

namespace blockmap::pipeline {
namespace {

double wrap_angle(double angle_rad) noexcept {
  return std::remainder(angle_rad, 2.0 * std::numbers::pi);
}

localize::Pose3 interpolated(const localize::Pose3& a, const localize::Pose3& b,
                             TimestampNs stamp_ns) noexcept {
  const double span_s = seconds_from_ns(b.stamp_ns - a.stamp_ns);
  const double f = span_s > 0.0 ? seconds_from_ns(stamp_ns - a.stamp_ns) / span_s : 0.0;
  const auto mix = [f](double x, double y) { return x + f * (y - x); };
  localize::Pose3 out;
  out.stamp_ns = stamp_ns;
  out.x_m = mix(a.x_m, b.x_m);
  out.y_m = mix(a.y_m, b.y_m);
  out.z_m = mix(a.z_m, b.z_m);
  out.roll_rad = mix(a.roll_rad, b.roll_rad);
  out.pitch_rad = mix(a.pitch_rad, b.pitch_rad);
  out.yaw_rad = wrap_angle(a.yaw_rad + f * wrap_angle(b.yaw_rad - a.yaw_rad));
  return out;
}

// Whether every laser scans a level plane (within scan_plane_angle_deg): its scan plane's
// normal is the mount's z axis, whose vertical part is cos(roll) cos(pitch).
bool is_level_laser(const MapperConfig& config, std::size_t laser) noexcept {
  const double cos_level = std::cos(config.scan_plane_angle_deg * std::numbers::pi / 180.0);
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

// The detector's blocks for a window of max_samples: a quarter of them (a city's window fills
// a block with 6-9 samples), but a block per sample up to 4,096 (a small window's samples are
// scattered: a window of 4,096 on benning had 900 samples more than a quarter's blocks held).
std::size_t window_blocks(std::size_t max_samples) noexcept {
  constexpr std::size_t kSmallWindowBlocks = 4096;
  return std::max(max_samples / 4, std::min(max_samples, kSmallWindowBlocks));
}

// The detector's configuration inside the mapper: it holds what the window holds. With level
// lasers only, a wall is a line in the map: the vertical plane through it.
planes::PlanesConfig detector_config(const MapperConfig& config) noexcept {
  planes::PlanesConfig planes = config.planes;
  planes.walls_from_lines = planes.walls_from_lines || only_level_lasers(config);
  planes.max_samples = config.window.max_samples;
  planes.max_blocks = planes.max_blocks == 0 ? window_blocks(planes.max_samples)
                                             : std::min(planes.max_blocks, planes.max_samples);
  planes.keep_shapes = config.incremental_extraction;
  return planes;
}

// Scans are matched only when drawn with the localizer's poses as they come: given poses (a
// survey's, the simulation's) are what the map should be drawn with, and the smoothed path of
// a pose lag already has the headings that matching gives the live poses (with both, benning's
// buildings came out worse: docs/localize.md, Scan matching).
localize::ScanMatchConfig matcher_config(const MapperConfig& config) noexcept {
  localize::ScanMatchConfig matching = config.scan_matching;
  matching.enabled = matching.enabled && config.pose_source == PoseSource::kLocalizer &&
                     !(config.localizer.map_pose_lag_s > 0.0);
  return matching;
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
// moved off it would no longer be the outline traced in it (the real UAL loop's block lost
// 60 % of its seen outline that way).
bool solves_the_path(const MapperConfig& config) noexcept {
  return config.rigid_path == RigidPath::kOn ||
         (config.rigid_path == RigidPath::kWhereScansAreMatched && matcher_config(config).enabled &&
          config.free_space.tiles_across == 0);
}

}  // namespace

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

std::string validate(const MapperConfig& config) {
  if (std::string problem = localize::validate(config.localizer); !problem.empty()) {
    return problem;
  }
  if (std::string problem = localize::validate(config.scan_matching); !problem.empty()) {
    return problem;
  }
  if (solves_the_path(config)) {
    if (std::string problem = localize::validate(config.path); !problem.empty()) {
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
  }
  if (std::string problem = map::validate(config.window); !problem.empty()) {
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
  if (std::abs(config.window.voxel_size_m - config.planes.sample_size_m) > 1e-9) {
    return "mapper: window.voxel_size_m must equal planes.sample_size_m";
  }
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

void Mapper::init(Arena& arena, const MapperConfig& config) {
  const std::string problem = validate(config);
  BLOCKMAP_CHECK_MSG(problem.empty(), "an invalid mapper configuration reached init()");
  config_ = config;
  localizer_.init(arena, config.localizer);
  matcher_.init(arena, matcher_config(config));
  path_on_ = solves_the_path(config);
  if (path_on_) {
    path_.init(arena, config.path);
  }
  for (std::size_t laser = 0; laser < config.laser_count; ++laser) {
    matches_scans_[laser] = matcher_.enabled() && is_level_laser(config, laser);
  }
  for (std::size_t i = 0; i < config.laser_count; ++i) {
    projectors_[i] = map::ScanProjector(config.laser_mounts[i], config.projection);
  }
  window_.init(arena, config.window);
  detector_.init(arena, detector_config(config));
  registry_.init(arena, registry_config(config));
  if (path_on_ && config.rigid_view) {
    registry_.set_view(&rigid_path_view_, config.rigid_view_change_m);
  }
  if (config.fit_buildings) {
    building_fitter_.init(arena, config.buildings, free_space_cells(config));
    free_space_.init(arena, config.free_space);
  }
  for (std::size_t laser = 0; laser < config.laser_count; ++laser) {
    carves_free_space_[laser] = free_space_.enabled() && is_level_laser(config, laser);
  }
  pending_ = arena.allocate_array<Pending>(config.reorder_capacity, "mapper.reorder");
  if (config.pose_source == PoseSource::kExternal) {
    poses_ = arena.allocate_array<localize::Pose3>(config.max_external_poses, "mapper.poses");
  }
  const std::size_t slots = scan_queue_slots(config);
  scans_ = arena.allocate_array<QueuedScan>(slots, "mapper.scans");
  scan_slots_ = arena.allocate_array<std::uint32_t>(slots, "mapper.scans");
  scan_codes_ = arena.allocate_array<std::uint16_t>(slots * config.max_beams, "mapper.scans");
  expanded_ = arena.allocate_array<msg::LaserScan>(1, "mapper.scans").data();
  for (std::size_t slot = 0; slot < scan_slots_.size(); ++slot) {
    scan_slots_[slot] = static_cast<std::uint32_t>(slot);
  }
  points_ = arena.allocate_array<Eigen::Vector3f>(msg::kMaxLaserBeams, "mapper.points");
  cos_scan_plane_angle_ = std::cos(config.scan_plane_angle_deg * std::numbers::pi / 180.0);
  sin_scan_plane_angle_ = std::sin(config.scan_plane_angle_deg * std::numbers::pi / 180.0);
  level_lasers_only_ = only_level_lasers(config);
}

std::size_t Mapper::arena_bytes(const MapperConfig& config) noexcept {
  constexpr std::size_t kSlack = 64;
  return localize::Localizer::arena_bytes(config.localizer) +
         localize::ScanMatcher::arena_bytes(matcher_config(config)) +
         (solves_the_path(config) ? localize::PathSmoother::arena_bytes(config.path) : 0) +
         map::VoxelWindow::arena_bytes(config.window) +
         planes::PlaneDetector::arena_budget_bytes(detector_config(config)) +
         map::PlaneRegistry::arena_bytes(registry_config(config)) +
         (config.fit_buildings
              ? buildings::BuildingFitter::arena_bytes(config.buildings, free_space_cells(config)) +
                    map::FreeSpaceGrid::arena_bytes(config.free_space)
              : 0) +
         config.reorder_capacity * sizeof(Pending) +
         (config.pose_source == PoseSource::kExternal ? config.max_external_poses : 0) *
             sizeof(localize::Pose3) +
         scan_queue_slots(config) * (sizeof(QueuedScan) + sizeof(std::uint32_t) +
                                     config.max_beams * sizeof(std::uint16_t)) +
         sizeof(msg::LaserScan) + msg::kMaxLaserBeams * sizeof(Eigen::Vector3f) + 7 * kSlack;
}

// --- Messages in --------------------------------------------------------------------------

void Mapper::on_base(const msg::OdometrySample& odometry, const msg::ImuSample& imu) noexcept {
  Pending message;
  message.stamp_ns = odometry.header.stamp_ns;
  message.kind = Kind::kBase;
  message.odometry = odometry;
  message.imu = imu;
  enqueue(message);
}

void Mapper::on_fix(const localize::GpsObservation& fix, double up_m) noexcept {
  Pending message;
  message.stamp_ns = fix.stamp_ns;
  message.kind = Kind::kFix;
  message.fix = fix;
  message.up_m = up_m;
  enqueue(message);
}

void Mapper::on_pose(const localize::Pose3& pose) noexcept {
  Pending message;
  message.stamp_ns = pose.stamp_ns;
  message.kind = Kind::kPose;
  message.pose = pose;
  enqueue(message);
}

bool Mapper::on_scan(std::size_t laser, const msg::LaserScan& scan) noexcept {
  ++counters_.scans;
  if (laser >= config_.laser_count) {
    ++counters_.scans_unknown_laser;
    return false;
  }
  if (scan_count_ == scans_.size()) {
    ++counters_.scans_refused_full;
    return false;
  }
  // The slots past the queue's end are the free ones.
  const std::uint32_t slot = scan_slots_[scan_count_];
  QueuedScan& queued = scans_[slot];
  if (!compact_scan(scan, queued.scan, codes_of(slot))) {
    ++counters_.scans_too_many_beams;
    return false;
  }
  queued.laser = laser;
  ++scan_count_;
  return true;
}

void Mapper::enqueue(const Pending& message) noexcept {
  if (released_any_ && message.stamp_ns < released_ns_) {
    ++counters_.messages_late;  // the localizer has moved past it
    return;
  }
  if (pending_count_ == pending_.size()) {
    ++counters_.reorder_forced;
    apply(pending_[0]);
    std::move(pending_.begin() + 1, pending_.begin() + static_cast<std::ptrdiff_t>(pending_count_),
              pending_.begin());
    --pending_count_;
  }
  // Insertion from the back: messages arrive nearly in order.
  std::size_t at = pending_count_;
  while (at > 0 && pending_[at - 1].stamp_ns > message.stamp_ns) {
    pending_[at] = pending_[at - 1];
    --at;
  }
  pending_[at] = message;
  ++pending_count_;
  newest_in_ns_ = std::max(newest_in_ns_, message.stamp_ns);
}

void Mapper::release_due() noexcept {
  const TimestampNs due_ns = newest_in_ns_ - ns_from_seconds(config_.reorder_window_s);
  std::size_t released = 0;
  while (released < pending_count_ && (ending_ || pending_[released].stamp_ns <= due_ns)) {
    apply(pending_[released]);
    ++released;
  }
  if (released > 0) {
    std::move(pending_.begin() + static_cast<std::ptrdiff_t>(released),
              pending_.begin() + static_cast<std::ptrdiff_t>(pending_count_), pending_.begin());
    pending_count_ -= released;
  }
}

void Mapper::apply(const Pending& message) noexcept {
  released_ns_ = message.stamp_ns;
  released_any_ = true;
  switch (message.kind) {
    case Kind::kBase:
      ++counters_.base_samples;
      released_base_ns_ = message.stamp_ns;
      released_base_any_ = true;
      localizer_.on_base(message.odometry, message.imu);
      break;
    case Kind::kFix:
      ++counters_.fixes;
      switch (localizer_.on_fix(message.fix, message.up_m)) {
        case localize::GpsOutcome::kRejected:
          ++counters_.fixes_rejected;
          return;  // an outlier to the filter is one to the path too
        case localize::GpsOutcome::kRecovered:
          ++counters_.fixes_recovered;
          break;
        default:
          break;
      }
      // A carrier-phase fix holds the scans where it puts them, unmatched (project()): no
      // matched scan will come for it to join.
      if (path_on_ && !localize::carrier_phase(message.fix.correction)) {
        if (path_fix_count_ == path_fixes_.size()) {
          path_fix_first_ = (path_fix_first_ + 1) % path_fixes_.size();
          --path_fix_count_;
          ++counters_.rigid_path_fixes_dropped;
        }
        // Where the filter put the robot frame for it: the antenna's mount taken out.
        path_fixes_[(path_fix_first_ + path_fix_count_) % path_fixes_.size()] =
            localizer_.last_robot_fix();
        ++path_fix_count_;
      }
      break;
    case Kind::kPose:
      ++counters_.poses;
      if (config_.pose_source == PoseSource::kExternal) {
        if (pose_count_ == poses_.size()) {
          pose_first_ = (pose_first_ + 1) % poses_.size();
          --pose_count_;
        }
        poses_[(pose_first_ + pose_count_) % poses_.size()] = message.pose;
        ++pose_count_;
      }
      break;
  }
}

// --- Poses ---------------------------------------------------------------------------------

bool Mapper::pose_horizon(TimestampNs& out) const noexcept {
  if (config_.pose_source == PoseSource::kExternal) {
    if (pose_count_ == 0) {
      return false;
    }
    out = poses_[(pose_first_ + pose_count_ - 1) % poses_.size()].stamp_ns;
    return true;
  }
  return localizer_.map_pose_horizon(out);
}

bool Mapper::pose_at(TimestampNs stamp_ns, localize::Pose3& out) const noexcept {
  if (config_.pose_source == PoseSource::kLocalizer) {
    return localizer_.map_pose_at(stamp_ns, out);
  }
  for (std::size_t k = 1; k < pose_count_; ++k) {
    const localize::Pose3& a = poses_[(pose_first_ + k - 1) % poses_.size()];
    const localize::Pose3& b = poses_[(pose_first_ + k) % poses_.size()];
    if (a.stamp_ns <= stamp_ns && stamp_ns <= b.stamp_ns) {
      out = interpolated(a, b, stamp_ns);
      return true;
    }
  }
  return false;
}

std::size_t Mapper::drain_final_poses(std::span<localize::Pose3> out) noexcept {
  return config_.pose_source == PoseSource::kLocalizer ? localizer_.drain_final(out) : 0;
}

std::size_t Mapper::smoothed_poses(std::span<localize::Pose3> out) const noexcept {
  return config_.pose_source == PoseSource::kLocalizer ? localizer_.smoothed_window(out) : 0;
}

// --- Scans ---------------------------------------------------------------------------------

std::ptrdiff_t Mapper::next_ready_scan(TimestampNs& oldest_waiting_ns) const noexcept {
  TimestampNs horizon_ns = 0;
  const bool have_poses = pose_horizon(horizon_ns);
  std::ptrdiff_t oldest = -1;
  TimestampNs oldest_ns = 0;
  oldest_waiting_ns = std::numeric_limits<TimestampNs>::max();
  // The queue is in arrival order, and messages arrive within reorder_window_s of time
  // order: past a scan that much newer than the horizon, none is covered, and none older
  // than the horizon waits. (With a pose lag the queue holds thousands of scans.)
  const TimestampNs last_useful_ns = horizon_ns + ns_from_seconds(config_.reorder_window_s);
  for (std::size_t i = 0; i < scan_count_; ++i) {
    const CompactScanHeader& scan = scans_[scan_slots_[i]].scan;
    if (have_poses && !ending_ && scan.header.stamp_ns > last_useful_ns) {
      break;
    }
    const bool covered = have_poses && scan.last_beam_ns <= horizon_ns;
    if (!covered) {
      oldest_waiting_ns = std::min(oldest_waiting_ns, scan.header.stamp_ns);
    }
    if ((covered || ending_) && (oldest < 0 || scan.header.stamp_ns < oldest_ns)) {
      oldest = static_cast<std::ptrdiff_t>(i);
      oldest_ns = scan.header.stamp_ns;
    }
  }
  return oldest;
}

void Mapper::remove_scan(std::size_t position) noexcept {
  // The queue's order is kept (equal stamps go in arrival order), and the slot joins the
  // free ones after the queue's end.
  const std::uint32_t slot = scan_slots_[position];
  for (std::size_t i = position; i + 1 < scan_count_; ++i) {
    scan_slots_[i] = scan_slots_[i + 1];
  }
  --scan_count_;
  scan_slots_[scan_count_] = slot;
}

void Mapper::record_laser_position(std::size_t laser, const localize::Pose3& pose) noexcept {
  LaserPath& path = laser_paths_[laser];
  Eigen::Vector3d origin_m;
  projectors_[laser].scan_plane(pose, origin_m, path.normal);
  const Eigen::Vector3d moved_m = origin_m - path.last_origin_m;
  if (moved_m.norm() < config_.scan_plane_spacing_m) {
    return;
  }
  path.last_origin_m = origin_m;
  // Only a laser moving within its own scan plane lays a sheet (a level laser, or a vertical
  // one looking along the way); one sweeping across the way paints a new slice each scan.
  if (std::abs(path.normal.dot(moved_m.normalized())) > sin_scan_plane_angle_) {
    return;
  }
  path.origins_m[path.next] = origin_m;
  path.next = (path.next + 1) % path.origins_m.size();
  path.count = std::min(path.count + 1, path.origins_m.size());
}

void Mapper::project(const QueuedScan& queued, std::span<const std::uint16_t> codes) noexcept {
  expand_scan(queued.scan, codes, *expanded_);
  const msg::LaserScan& scan = *expanded_;
  const TimestampNs first_ns = scan.header.stamp_ns;
  const TimestampNs last_ns = queued.scan.last_beam_ns;
  localize::Pose3 first;
  localize::Pose3 last;
  TimestampNs horizon_ns = 0;
  const bool have_poses = pose_horizon(horizon_ns);
  // At the end of input a scan may reach a few milliseconds past the last pose: it takes the
  // last one for those beams rather than being lost.
  const bool found = have_poses && pose_at(std::min(first_ns, horizon_ns), first) &&
                     pose_at(std::min(last_ns, horizon_ns), last);
  if (!found) {
    ++counters_.scans_without_pose;
    return;
  }
  if (level_lasers_only_) {
    // No laser here sees a height, and the GPS's wanders by metres: a level laser's returns
    // drawn at it would be sheets at many heights, and each wall a ladder of lines.
    if (!height_held_) {
      height_held_ = true;
      held_z_m_ = first.z_m;
    }
    first.z_m = held_z_m_;
    last.z_m = held_z_m_;
  }
  const std::size_t count = projectors_[queued.laser].project(scan, first, last, points_);
  if (matcher_.enabled()) {
    if (!localizer_.carrier_phase_holds(first.stamp_ns)) {
      correct_by_scan_matching(queued.laser, first, last, points_.first(count));
    } else if (!matching_paused_) {
      // Centimetre fixes hold the poses tighter than a scan matcher's own drift: the scans
      // are drawn as the filter puts them. The matcher's grid starts over when they stop.
      matching_paused_ = true;
      ++counters_.scan_matching_pauses;
    }
  }
  // The window follows the robot: tiles it leaves behind go to the registry as they leave.
  window_.recentre(Eigen::Vector2d(first.x_m, first.y_m), tile_leaving_);
  // A window reaching beyond its core keeps room for this scan's new voxels.
  window_.make_room(tile_leaving_);
  record_laser_position(queued.laser, first);
  if (carves_free_space_[queued.laser]) {
    carve_free_space(queued.laser, first, points_.first(count));
  }
  if (point_sink_ != nullptr) {
    point_sink_->on_points(points_.first(count));
  }
  // The map leaves out the ground far from the laser (ScanProjectorConfig says why).
  const std::size_t mapped = projectors_[queued.laser].drop_far_ground(first, points_.first(count));
  window_.add_points(points_.first(mapped));
  counters_.points += count;
  ++counters_.scans_projected;
  last_scan_ns_ = std::max(last_scan_ns_, last_ns);
}

void Mapper::correct_by_scan_matching(std::size_t laser, localize::Pose3& first,
                                      localize::Pose3& last,
                                      std::span<Eigen::Vector3f> points_m) noexcept {
  localize::PlanarCorrection correction;
  localize::Pose3 drawn;
  localize::Pose2 odometry;
  if (matches_scans_[laser] && localizer_.map_pose_at(first.stamp_ns, drawn, &odometry)) {
    // The filter's poses jumped to its estimate (its start, a recovery) since the last
    // matched scan: the grid drawn with the poses before is of another frame. By the snap's
    // stamp, not by when the localizer made it: it runs ahead of the scans by however the
    // messages came.
    if (matching_paused_ ||
        localizer_.map_pose_snapped_between(last_matched_scan_ns_, first.stamp_ns)) {
      matching_paused_ = false;
      matcher_.reset();
      path_rebase_due_ = true;  // the matcher's frame starts over
    }
    last_matched_scan_ns_ = first.stamp_ns;
    const localize::Pose2 raw{first.stamp_ns, first.x_m, first.y_m, first.yaw_rad};
    correction = matcher_.add_scan(raw, odometry, first.z_m, points_m);
    if (path_on_) {
      feed_rigid_path(first.stamp_ns, correction.apply(raw), odometry);
    }
    corrections_[correction_next_] = {first.stamp_ns, correction};
    correction_next_ = (correction_next_ + 1) % corrections_.size();
    correction_count_ = std::min(correction_count_ + 1, corrections_.size());
  } else {
    // Another laser's scan takes the correction of the last matched scan before it. By stamp:
    // a later scan of the matched laser may have been drawn first (it ended sooner).
    TimestampNs best_ns = 0;
    bool found = false;
    for (std::size_t i = 0; i < correction_count_; ++i) {
      const StampedCorrection& kept = corrections_[i];
      if (kept.stamp_ns <= first.stamp_ns && (!found || kept.stamp_ns > best_ns)) {
        best_ns = kept.stamp_ns;
        correction = kept.correction;
        found = true;
      }
    }
  }
  correction.apply(points_m);
  for (localize::Pose3* pose : {&first, &last}) {
    const localize::Pose2 moved =
        correction.apply(localize::Pose2{pose->stamp_ns, pose->x_m, pose->y_m, pose->yaw_rad});
    pose->x_m = moved.x_m;
    pose->y_m = moved.y_m;
    pose->yaw_rad = moved.yaw_rad;
  }
}

void Mapper::feed_rigid_path(TimestampNs stamp_ns, const localize::Pose2& drawn,
                             const localize::Pose2& odometry) noexcept {
  // Every 10 s of scan time the path is solved again, so that each solve starts
  // near its answer (a sweep is O(keyframes)).
  constexpr TimestampNs kSolveEveryNs = 10'000'000'000;
  if (path_rebase_due_ && path_have_last_) {
    // Where the dead reckoning carries the last pose (the rigid motion that lays the last
    // odometry pose on the last path pose, applied to this one): the new frame's first pose
    // goes there.
    const localize::Pose2 carried =
        localize::motion_between(path_last_odometry_, path_last_pose_).apply(odometry);
    path_rebase_ = localize::motion_between(matcher_.matched(), carried);
  }
  path_rebase_due_ = false;
  localize::Pose2 matched = path_rebase_.apply(matcher_.matched());
  matched.stamp_ns = stamp_ns;
  path_have_last_ = true;
  path_last_pose_ = matched;
  path_last_odometry_ = odometry;
  localize::Pose2 drawn_at = drawn;
  drawn_at.stamp_ns = stamp_ns;
  bool added = false;
  while (path_fix_count_ > 0 && path_fixes_[path_fix_first_].stamp_ns <= stamp_ns) {
    const localize::GpsObservation& fix = path_fixes_[path_fix_first_];
    path_.add(matched, drawn_at, Eigen::Vector2d(fix.east_m, fix.north_m), std::max(fix.hdop, 0.5),
              fix.correction);
    path_fix_first_ = (path_fix_first_ + 1) % path_fixes_.size();
    --path_fix_count_;
    added = true;
  }
  if (!added) {
    path_.add(matched, drawn_at, std::nullopt);
  }
  if (stamp_ns >= next_path_solve_ns_) {
    path_.solve();
    path_solved_ = true;
    next_path_solve_ns_ = stamp_ns + kSolveEveryNs;
  }
}

void Mapper::move_planes_by_rigid_path() noexcept {
  // The final solve has been made (step()); the planes go where it puts them, for good.
  counters_.planes_moved += registry_.move_finals_by(rigid_path_view_);
}

std::size_t Mapper::first_keyframe_from(TimestampNs stamp_ns) const noexcept {
  std::size_t low = 0;
  std::size_t high = path_.keyframe_count();
  while (low < high) {
    const std::size_t middle = low + (high - low) / 2;
    if (path_.drawn(middle).stamp_ns < stamp_ns) {
      low = middle + 1;
    } else {
      high = middle;
    }
  }
  return low;
}

map::PlaneMove Mapper::rigid_path_move(const msg::PlanePatch& plane,
                                       const map::SeenSpans& seen) const noexcept {
  // A plane moves by the corrections of the keyframes that drew it: near it (within the
  // lasers' reach, nearer ones more: they put more points on it) while it was being seen (a
  // pass behind the building, as near, did not draw it), averaged: a turn about the vertical
  // and where its centroid goes. A detection holds points drawn up to kLeadNs before the
  // plane was first matched (it takes points before it is found).
  constexpr double kReachM = 30.0;
  constexpr double kNearM = 2.0;
  constexpr TimestampNs kLeadNs = 10 * kNanosecondsPerSecond;
  // Without fixes nothing says where the path lies but its own odometry, which the scans
  // were drawn with already (a log with no GPS): the planes stay.
  // A plane without seen spans comes from a snapshot: the run that saved it placed it.
  const std::size_t keyframes = path_.keyframe_count();
  if (path_.counters().fixes == 0 || path_.counters().solves == 0 || keyframes < 2 ||
      seen.count == 0) {
    return {};
  }
  Eigen::AlignedBox2d extent;
  for (std::size_t v = 0; v < plane.polygon_size; ++v) {
    extent.extend(plane.polygon_m[v].head<2>());
  }
  if (extent.isEmpty()) {
    extent.extend(plane.centroid_m.head<2>());
  }
  // The keyframes of its spans (they are in time order).
  const std::size_t first = first_keyframe_from(seen.first_ns() - kLeadNs);
  const std::size_t end = first_keyframe_from(seen.last_ns() + 1);
  const Eigen::Vector2d centroid_m = plane.centroid_m.head<2>();
  double weight_sum = 0.0;
  double yaw_sum_rad = 0.0;
  Eigen::Vector2d moved_sum_m = Eigen::Vector2d::Zero();
  for (std::size_t k = first; k < end; ++k) {
    const localize::Pose2& drawn = path_.drawn(k);
    if (!seen.covers(drawn.stamp_ns, kLeadNs)) {
      continue;
    }
    const double distance_m =
        std::sqrt(extent.squaredExteriorDistance(Eigen::Vector2d(drawn.x_m, drawn.y_m)));
    if (distance_m > kReachM) {
      continue;
    }
    const double weight = 1.0 / std::max(distance_m * distance_m, kNearM * kNearM);
    const localize::PlanarCorrection correction = path_.correction(k);
    weight_sum += weight;
    yaw_sum_rad += weight * correction.yaw_rad;
    moved_sum_m += weight * correction.apply(centroid_m);
  }
  if (weight_sum <= 0.0) {
    return {};
  }
  map::PlaneMove move;
  move.yaw_rad = yaw_sum_rad / weight_sum;
  const Eigen::Vector2d to_m = moved_sum_m / weight_sum;
  move.shift_m = Eigen::Vector3d(to_m.x(), to_m.y(), plane.centroid_m.z()) -
                 move.rotation() * plane.centroid_m;
  return move;
}

namespace {

// A wall's extent along its own direction (`along`, horizontal) and in height.
struct WallExtent {
  double from_m = std::numeric_limits<double>::infinity();
  double to_m = -std::numeric_limits<double>::infinity();
  double low_m = std::numeric_limits<double>::infinity();
  double high_m = -std::numeric_limits<double>::infinity();
};

WallExtent wall_extent(const msg::PlanePatch& wall, const Eigen::Vector2d& along) noexcept {
  WallExtent extent;
  for (std::size_t v = 0; v < wall.polygon_size; ++v) {
    const Eigen::Vector3d& vertex = wall.polygon_m[v];
    const double at_m = along.dot(vertex.head<2>());
    extent.from_m = std::min(extent.from_m, at_m);
    extent.to_m = std::max(extent.to_m, at_m);
    extent.low_m = std::min(extent.low_m, vertex.z());
    extent.high_m = std::max(extent.high_m, vertex.z());
  }
  return extent;
}

double overlap_m(double a_from, double a_to, double b_from, double b_to) noexcept {
  return std::min(a_to, b_to) - std::max(a_from, b_from);
}

}  // namespace

void Mapper::tie_walls_to_earlier_passes(std::span<const msg::PlanePatch> detected,
                                         TimestampNs stamp_ns) noexcept {
  // A pass's poses put its walls off by the receiver's slow error of that time, up to a
  // couple of metres, and another pass's by another: the same wall drawn twice lies up to
  // kGateM apart, parallel to within kGateAngle. It must overlap the earlier drawing by
  // kMinOverlapM along the wall and in height (the walls of a street's next building are in
  // line with it, but further on), and the earlier pass must have ended kOtherPassNs before
  // (a wall left behind by this pass is no earlier pass). Of several, the nearest.
  constexpr double kGateM = 2.0;
  const double cos_gate_angle = std::cos(5.0 * std::numbers::pi / 180.0);
  constexpr double kMinOverlapM = 2.0;
  constexpr double kMinHeightOverlapM = 0.5;
  constexpr TimestampNs kOtherPassNs = 2 * map::SeenSpans::kJoinGapNs;
  // The later look's keyframe: one of this pass, the last half minute.
  constexpr TimestampNs kThisPassNs = 30 * kNanosecondsPerSecond;
  const std::span<const msg::PlanePatch> finals = registry_.final_planes();
  for (const msg::PlanePatch& wall : detected) {
    if (wall.kind != msg::PlaneKind::kWall || wall.normal.head<2>().norm() < 0.5) {
      continue;
    }
    const Eigen::Vector2d normal = wall.normal.head<2>().normalized();
    const Eigen::Vector2d along(-normal.y(), normal.x());
    const WallExtent extent = wall_extent(wall, along);
    std::size_t best = finals.size();
    double best_offset_m = kGateM;
    for (std::size_t j = 0; j < finals.size(); ++j) {
      const msg::PlanePatch& earlier = finals[j];
      const map::SeenSpans& seen = registry_.seen_spans(j);
      if (earlier.kind != msg::PlaneKind::kWall || seen.count == 0 ||
          stamp_ns - seen.last_ns() < kOtherPassNs ||
          std::abs(earlier.normal.head<2>().normalized().dot(normal)) < cos_gate_angle) {
        continue;
      }
      const double offset_m = std::abs(earlier.normal.dot(wall.centroid_m) - earlier.d_m);
      if (offset_m >= best_offset_m) {
        continue;
      }
      const WallExtent before = wall_extent(earlier, along);
      if (overlap_m(extent.from_m, extent.to_m, before.from_m, before.to_m) < kMinOverlapM ||
          overlap_m(extent.low_m, extent.high_m, before.low_m, before.high_m) <
              kMinHeightOverlapM) {
        continue;
      }
      best = j;
      best_offset_m = offset_m;
    }
    if (best == finals.size()) {
      continue;
    }
    const msg::PlanePatch& earlier = finals[best];
    const map::SeenSpans& seen = registry_.seen_spans(best);
    localize::WallLook before{0, earlier.normal.head<2>().normalized(),
                              earlier.centroid_m.head<2>()};
    localize::WallLook now{0, normal, wall.centroid_m.head<2>()};
    Eigen::Vector2d before_from_m;
    Eigen::Vector2d now_from_m;
    if (!keyframe_that_drew(before.point_m, seen.first_ns(), seen.last_ns(), &seen, before.stamp_ns,
                            before_from_m) ||
        !keyframe_that_drew(now.point_m, stamp_ns - kThisPassNs, stamp_ns, nullptr, now.stamp_ns,
                            now_from_m)) {
      continue;
    }
    // Both looks from the same side: a wall's two faces (or two walls back to back) are not
    // one surface.
    if (before.normal.dot(before_from_m - before.point_m) *
            before.normal.dot(now_from_m - now.point_m) <=
        0.0) {
      ++counters_.rigid_path_ties_other_side;
      continue;
    }
    path_.tie(earlier.id, before, now);
  }
}

bool Mapper::keyframe_that_drew(const Eigen::Vector2d& point_m, TimestampNs from_ns,
                                TimestampNs to_ns, const map::SeenSpans* seen,
                                TimestampNs& stamp_ns, Eigen::Vector2d& from_m) const noexcept {
  // Within the lasers' reach of the wall's middle, the nearest (it put the most points there).
  constexpr double kReachM = 30.0;
  constexpr TimestampNs kLeadNs = 10 * kNanosecondsPerSecond;  // as rigid_path_move
  double best_m2 = kReachM * kReachM;
  bool found = false;
  // Back from the last keyframe of the time (the keyframes are in time order).
  for (std::size_t k = first_keyframe_from(to_ns + 1); k-- > 0;) {
    const localize::Pose2& drawn = path_.drawn(k);
    if (drawn.stamp_ns < from_ns - kLeadNs) {
      break;
    }
    if (seen != nullptr && !seen->covers(drawn.stamp_ns, kLeadNs)) {
      continue;
    }
    const double distance_m2 = (Eigen::Vector2d(drawn.x_m, drawn.y_m) - point_m).squaredNorm();
    if (distance_m2 < best_m2) {
      best_m2 = distance_m2;
      stamp_ns = drawn.stamp_ns;
      from_m = Eigen::Vector2d(drawn.x_m, drawn.y_m);
      found = true;
    }
  }
  return found;
}

void Mapper::carve_free_space(std::size_t laser, const localize::Pose3& pose,
                              std::span<const Eigen::Vector3f> points_m) noexcept {
  // The laser's position at the scan's first beam: it moves a few decimetres in a scan, less
  // than a cell of the grid.
  Eigen::Vector3d origin_m;
  Eigen::Vector3d normal;
  projectors_[laser].scan_plane(pose, origin_m, normal);
  const Eigen::Vector2d from_m = origin_m.head<2>();
  for (const Eigen::Vector3f& point : points_m) {
    free_space_.add_beam(from_m, point.head<2>().cast<double>());
  }
}

// --- Planes --------------------------------------------------------------------------------

void Mapper::extract(TimestampNs stamp_ns) noexcept {
  ++counters_.extractions;
  registry_.finalize_outside(window_.bounds_m());
  give_detector_the_window();
  // The lasers' own scan planes are not surfaces (PlaneExclusion).
  std::array<planes::PlaneExclusion, kMaxLasers> exclusions{};
  std::size_t exclusion_count = 0;
  for (std::size_t laser = 0; laser < config_.laser_count; ++laser) {
    const LaserPath& path = laser_paths_[laser];
    if (path.count > 0) {
      exclusions[exclusion_count++] = {std::span(path.origins_m).first(path.count), path.normal,
                                       cos_scan_plane_angle_, config_.scan_plane_distance_m};
    }
  }
  detector_.set_exclusions(std::span(exclusions).first(exclusion_count));
  const std::span<const msg::PlanePatch> planes = detector_.detect();
  counters_.peak_blocks = std::max(counters_.peak_blocks, detector_.voxels().block_count());
  counters_.peak_samples_without_room =
      std::max(counters_.peak_samples_without_room,
               window_.size() - std::min(window_.size(), detector_.voxels().size()));
  counters_.peak_section_planes = std::max(
      counters_.peak_section_planes, static_cast<std::size_t>(detector_.stats().section_planes));
  counters_.peak_detected_planes = std::max(counters_.peak_detected_planes, planes.size());
  counters_.scan_planes_rejected += detector_.stats().planes_excluded;
  counters_.sections_searched += detector_.stats().sections_searched;
  counters_.sections_replayed += detector_.stats().sections_replayed;
  counters_.sections_still_barren += detector_.stats().sections_still_barren;
  counters_.sections_settled += detector_.stats().sections_settled;
  if (path_on_) {
    tie_walls_to_earlier_passes(planes, stamp_ns);
  }
  registry_.update(planes, detector_.plane_moments(), stamp_ns);
  update_stamp_ns_ = stamp_ns;
  refit_buildings();
  if (path_solved_) {
    path_solved_ = false;
    view_due_ = path_on_ && config_.rigid_view;
  }
}

void Mapper::restore_planes(std::span<const map::SavedPlane> planes) noexcept {
  registry_.restore(planes);
  if (config_.fit_buildings) {
    fit_buildings_to_map();
  }
}

void Mapper::fit_buildings_to_map() noexcept {
  building_fitter_.begin();
  if (free_space_.enabled()) {
    building_fitter_.set_free_space(free_space_.raster());
  }
  registry_.for_each_plane([this](const msg::PlanePatch& plane) { building_fitter_.add(plane); });
  building_fitter_.finish();
}

void Mapper::refit_buildings() noexcept {
  // The buildings follow from the registry's planes alone: no change there, none here.
  if (!config_.fit_buildings || registry_.changes().empty()) {
    return;
  }
  fit_buildings_to_map();
}

void Mapper::TileLeaving::on_evicted(const map::VoxelWindow::EvictedTile& tile) noexcept {
  mapper_->registry_.on_evicted(tile);
  if (mapper_->config_.incremental_extraction && mapper_->extracted_before_) {
    // The detector's table is read at random: each sample's slot is fetched a few ahead.
    constexpr std::size_t kAhead = 8;
    const std::span<const planes::VoxelSums> samples = tile.samples;
    for (std::size_t i = 0; i < std::min(kAhead, samples.size()); ++i) {
      mapper_->detector_.prefetch_sample(samples[i].key);
    }
    for (std::size_t i = 0; i < samples.size(); ++i) {
      if (i + kAhead < samples.size()) {
        mapper_->detector_.prefetch_sample(samples[i + kAhead].key);
      }
      mapper_->detector_.remove_sample(samples[i].key);
    }
  }
}

void Mapper::give_detector_the_window() noexcept {
  // The detector keeps its grid from one extraction to the next and is given only the samples
  // that gained points (samples that left went as their tile did); or it starts over.
  if (config_.incremental_extraction && extracted_before_) {
    // The detector's table is read at random: each sample's slot is fetched a few ahead.
    window_.for_each_touched(
        [this](const planes::VoxelSums& sample) { detector_.set_sample(sample); },
        [this](const planes::VoxelSums& sample) { detector_.prefetch_sample(sample.key); });
    ++counters_.incremental_extractions;
  } else {
    detector_.clear();
    window_.for_each_sample(
        [this](const planes::VoxelSums& sample) { detector_.add_sample(sample); });
  }
  window_.forget_touched();
  extracted_before_ = true;
}

void Mapper::drop_scans_before_first_pose() noexcept {
  TimestampNs horizon_ns = 0;
  if (pose_horizon(horizon_ns) || scan_count_ == 0) {
    return;
  }
  // No pose yet, with the messages up to released_ns_ applied. The first pose will be no
  // older than the next one released (external poses), or than the last base sample released
  // less the pose lag (the filter's: it starts at a fix not yet released, drawn at the base
  // sample before it, and lagged poses reach back by the lag). A scan that starts before that
  // can never be drawn: it leaves the queue now, rather than when the first pose comes. A
  // filter waiting for its first fix would otherwise fill the queue, and how full it got would
  // depend on how the messages were batched between steps. The extraction periods start from
  // the first scan, as when it is drawn.
  TimestampNs first_pose_bound_ns = 0;
  if (config_.pose_source == PoseSource::kExternal) {
    if (!released_any_) {
      return;
    }
    first_pose_bound_ns = released_ns_;
  } else {
    if (!released_base_any_) {
      return;
    }
    first_pose_bound_ns = released_base_ns_ - ns_from_seconds(config_.localizer.map_pose_lag_s);
  }
  TimestampNs oldest_ns = std::numeric_limits<TimestampNs>::max();
  for (std::size_t i = 0; i < scan_count_; ++i) {
    oldest_ns = std::min(oldest_ns, scans_[scan_slots_[i]].scan.header.stamp_ns);
  }
  if (oldest_ns >= first_pose_bound_ns) {
    return;
  }
  if (!extraction_scheduled_) {
    extraction_scheduled_ = true;
    next_extraction_ns_ = oldest_ns + ns_from_seconds(config_.extract_every_s);
  }
  for (std::size_t i = 0; i < scan_count_;) {
    if (scans_[scan_slots_[i]].scan.header.stamp_ns < first_pose_bound_ns) {
      ++counters_.scans_without_pose;
      remove_scan(i);
    } else {
      ++i;
    }
  }
}

bool Mapper::step() noexcept {
  registry_.begin_update();
  changes_ = {};
  if (view_due_ && final_extracted_) {
    view_due_ = false;  // the end's solve and move come next, and report every plane moved
  }
  if (view_due_) {
    // The path was solved again before the last extraction: the planes where it puts them
    // now, as updates of their own at that extraction's time, each within one datagram
    // (128 entries of at most 427 bytes).
    constexpr std::size_t kViewChangesPerUpdate = 128;
    view_due_ = !registry_.refresh_view(kViewChangesPerUpdate);
    if (!registry_.changes().empty()) {
      refit_buildings();
      changes_ = registry_.changes();
      return true;
    }
  }
  release_due();
  drop_scans_before_first_pose();
  TimestampNs oldest_waiting_ns = 0;
  for (std::ptrdiff_t next = next_ready_scan(oldest_waiting_ns); next >= 0;
       next = next_ready_scan(oldest_waiting_ns)) {
    const auto position = static_cast<std::size_t>(next);
    const std::uint32_t slot = scan_slots_[position];
    const QueuedScan& queued = scans_[slot];
    const TimestampNs stamp_ns = queued.scan.header.stamp_ns;
    if (ending_ && pending_count_ == 0) {
      localizer_.flush_map_pose(queued.scan.last_beam_ns);  // the last lag's scans
    }
    if (!extraction_scheduled_) {
      // From the oldest scan queued, covered or not: the same periods however the messages
      // were batched between steps.
      extraction_scheduled_ = true;
      next_extraction_ns_ =
          std::min(stamp_ns, oldest_waiting_ns) + ns_from_seconds(config_.extract_every_s);
    }
    if (stamp_ns >= next_extraction_ns_ && !ending_ && oldest_waiting_ns < next_extraction_ns_) {
      // A scan of the period still waits for its poses (a laser whose scans take longer
      // ends later): the extraction waits for it, so that what it holds does not depend on
      // how the messages were batched between two steps.
      break;
    }
    if (stamp_ns >= next_extraction_ns_ && window_.placed()) {
      // Every scan before this one is in: the planes of the last period.
      extract(next_extraction_ns_);
      while (next_extraction_ns_ <= stamp_ns) {  // a gap in the scans is one extraction
        next_extraction_ns_ += ns_from_seconds(config_.extract_every_s);
      }
      changes_ = registry_.changes();
      return true;
    }
    project(queued, codes_of(slot));
    remove_scan(position);
  }
  if (!ending_ || pending_count_ > 0) {
    return false;
  }
  if (!final_extracted_) {
    final_extracted_ = true;
    if (window_.placed()) {
      extract(last_scan_ns_);
      changes_ = registry_.changes();
      return true;
    }
  }
  if (!finalized_) {
    finalized_ = true;
    if (path_on_ && path_.counters().fixes > 0) {
      path_.solve();  // the whole run's path: the planes finalized now are shown where it puts them
    }
    registry_.finalize_all();
    if (path_on_) {
      move_planes_by_rigid_path();
    }
    update_stamp_ns_ = last_scan_ns_;
    refit_buildings();
    changes_ = registry_.changes();
    return true;
  }
  return false;
}

}  // namespace blockmap::pipeline
