#include "blockmap/pipeline/mapper.hpp"

#include <algorithm>
#include <cmath>

#include "blockmap/core/check.hpp"

namespace blockmap::pipeline {

void Mapper::init(Arena& arena, const MapperConfig& config) {
  const std::string problem = validate(config);
  BLOCKMAP_CHECK_MSG(problem.empty(), "an invalid mapper configuration reached init()");
  config_ = config;
  poses_.init(arena, config.pose_source, config.localizer, config.max_external_poses);
  std::array<bool, kMaxLasers> level{};
  for (std::size_t laser = 0; laser < config.laser_count; ++laser) {
    level[laser] = is_level_laser(config, laser);
  }
  scan_correction_.init(arena, matcher_config(config), level);
  path_on_ = solves_the_path(config);
  if (path_on_) {
    path_.init(arena, path_config(config), config.loop_closure, config.prior_map);
    if (config.localizer.start_at_known_pose) {
      path_.start_placed(config.localizer.start_position_sigma_m,
                         config.localizer.start_yaw_sigma_rad);
    }
  }
  for (std::size_t i = 0; i < config.laser_count; ++i) {
    projectors_[i] = map::ScanProjector(config.laser_mounts[i], config.projection);
  }
  window_.init(arena, window_config(config));
  detector_.init(arena, detector_config(config));
  registry_.init(arena, registry_config(config));
  if (path_on_ && config.rigid_view) {
    registry_.set_view(&path_, config.rigid_view_change_m);
  }
  if (config.fit_buildings) {
    building_fitter_.init(arena, config.buildings, free_space_cells(config));
    free_space_.init(arena, config.free_space);
  }
  for (std::size_t laser = 0; laser < config.laser_count; ++laser) {
    carves_free_space_[laser] = free_space_.enabled() && level[laser];
  }
  reorder_.init(arena, config.reorder_capacity, config.reorder_window_s);
  const std::size_t slots = scan_queue_slots(config);
  scans_.init(arena, slots, config.max_beams);
  points_ = arena.allocate_array<Eigen::Vector3f>(msg::kMaxLaserBeams, "mapper.points");
  scan_planes_.init(config.scan_plane_angle_deg, config.scan_plane_distance_m,
                    config.scan_plane_spacing_m);
  level_lasers_only_ = only_level_lasers(config);
}

std::size_t Mapper::arena_bytes(const MapperConfig& config) noexcept {
  constexpr std::size_t kSlack = 64;
  return ScanPoses::arena_bytes(config.pose_source, config.localizer, config.max_external_poses) +
         ScanCorrection::arena_bytes(matcher_config(config)) +
         (solves_the_path(config) ? RigidPathSolver::arena_bytes(
                                        path_config(config), config.loop_closure, config.prior_map)
                                  : 0) +
         map::VoxelWindow::arena_bytes(window_config(config)) +
         planes::PlaneDetector::arena_budget_bytes(detector_config(config)) +
         map::PlaneRegistry::arena_bytes(registry_config(config)) +
         (config.fit_buildings
              ? buildings::BuildingFitter::arena_bytes(config.buildings, free_space_cells(config)) +
                    map::FreeSpaceGrid::arena_bytes(config.free_space)
              : 0) +
         ReorderBuffer::arena_bytes(config.reorder_capacity) +
         ScanQueue::arena_bytes(scan_queue_slots(config), config.max_beams) +
         msg::kMaxLaserBeams * sizeof(Eigen::Vector3f) + 7 * kSlack;
}

// --- Messages in --------------------------------------------------------------------------

void Mapper::on_base(const msg::OdometrySample& odometry, const msg::ImuSample& imu) noexcept {
  TimedMessage message;
  message.stamp_ns = odometry.header.stamp_ns;
  message.kind = TimedMessage::Kind::kBase;
  message.odometry = odometry;
  message.imu = imu;
  enqueue(message);
}

void Mapper::on_fix(const localize::GpsObservation& fix, double up_m) noexcept {
  TimedMessage message;
  message.stamp_ns = fix.stamp_ns;
  message.kind = TimedMessage::Kind::kFix;
  message.fix = fix;
  message.up_m = up_m;
  enqueue(message);
}

void Mapper::on_pose(const localize::Pose3& pose) noexcept {
  TimedMessage message;
  message.stamp_ns = pose.stamp_ns;
  message.kind = TimedMessage::Kind::kPose;
  message.pose = pose;
  enqueue(message);
}

bool Mapper::on_scan(std::size_t laser, const msg::LaserScan& scan) noexcept {
  ++counters_.scans;
  if (laser >= config_.laser_count) {
    ++counters_.scans_unknown_laser;
    return false;
  }
  switch (scans_.push(laser, scan)) {
    case ScanQueue::Outcome::kFull:
      ++counters_.scans_refused_full;
      return false;
    case ScanQueue::Outcome::kTooManyBeams:
      ++counters_.scans_too_many_beams;
      return false;
    case ScanQueue::Outcome::kQueued:
      break;
  }
  return true;
}

void Mapper::enqueue(const TimedMessage& message) noexcept {
  switch (reorder_.add(message, [this](const TimedMessage& early) { feed_poses(early); })) {
    case ReorderBuffer::Outcome::kLate:
      ++counters_.messages_late;  // the localizer has moved past it
      break;
    case ReorderBuffer::Outcome::kForcedEarly:
      ++counters_.reorder_forced;
      break;
    case ReorderBuffer::Outcome::kQueued:
      break;
  }
}

void Mapper::feed_poses(const TimedMessage& message) noexcept {
  switch (message.kind) {
    case TimedMessage::Kind::kBase:
      ++counters_.base_samples;
      poses_.on_base(message.odometry, message.imu);
      break;
    case TimedMessage::Kind::kFix:
      ++counters_.fixes;
      switch (poses_.on_fix(message.fix, message.up_m)) {
        case localize::GpsOutcome::kRejected:
          ++counters_.fixes_rejected;
          return;  // an outlier to the filter is one to the path too
        case localize::GpsOutcome::kRecovered:
          ++counters_.fixes_recovered;
          break;
        default:
          break;
      }
      // A carrier-phase fix holds the scans where it puts them, unmatched (draw_scan()): no
      // matched scan will come for it to join.
      if (path_on_ && !localize::carrier_phase(message.fix.correction)) {
        // Where the filter put the robot frame for it: the antenna's mount taken out.
        path_.add_fix(poses_.localizer().last_robot_fix());
      }
      break;
    case TimedMessage::Kind::kPose:
      ++counters_.poses;
      poses_.on_pose(message.pose);
      break;
  }
}

// --- Poses ---------------------------------------------------------------------------------

std::size_t Mapper::drain_final_poses(std::span<localize::Pose3> out) noexcept {
  return config_.pose_source == PoseSource::kLocalizer ? poses_.localizer().drain_final(out)
                                                       : poses_.drain_given(out);
}

std::size_t Mapper::smoothed_poses(std::span<localize::Pose3> out) const noexcept {
  return config_.pose_source == PoseSource::kLocalizer ? poses_.localizer().smoothed_window(out)
                                                       : 0;
}

// --- Scans ---------------------------------------------------------------------------------

std::ptrdiff_t Mapper::next_ready_scan(TimestampNs& oldest_waiting_ns) const noexcept {
  TimestampNs horizon_ns = 0;
  const bool have_poses = poses_.horizon(horizon_ns);
  return scans_.next_ready(have_poses, horizon_ns, ns_from_seconds(config_.reorder_window_s),
                           ending_, oldest_waiting_ns);
}

void Mapper::draw_scan(std::size_t position) noexcept {
  const std::size_t laser = scans_.laser(position);
  const TimestampNs last_ns = scans_.header(position).last_beam_ns;
  const msg::LaserScan& scan = scans_.expand(position);
  localize::Pose3 first;
  localize::Pose3 last;
  if (!poses_of_scan(scan.header.stamp_ns, last_ns, first, last)) {
    ++counters_.scans_without_pose;
    return;
  }
  const std::size_t count = projectors_[laser].project(scan, first, last, points_);
  const std::span<Eigen::Vector3f> points_m = points_.first(count);
  if (scan_correction_.correct(laser, poses_.localizer(), path_on_ ? &path_ : nullptr, first, last,
                               points_m) == ScanCorrection::Outcome::kPaused) {
    ++counters_.scan_matching_pauses;
  }
  // The window follows the robot: tiles it leaves behind go to the registry as they leave.
  window_.recentre(Eigen::Vector2d(first.x_m, first.y_m), tile_leaving_);
  // A window reaching beyond its core keeps room for this scan's new voxels.
  window_.make_room(tile_leaving_);
  scan_planes_.record(laser, projectors_[laser], first);
  if (carves_free_space_[laser]) {
    carve_free_space(laser, first, points_m);
  }
  if (point_sink_ != nullptr) {
    point_sink_->on_points(points_m);
  }
  // The map leaves out the ground far from the laser (ScanProjectorConfig says why).
  const std::size_t mapped = projectors_[laser].drop_far_ground(first, points_m);
  window_.add_points(points_.first(mapped));
  counters_.points += count;
  ++counters_.scans_projected;
  last_scan_ns_ = std::max(last_scan_ns_, last_ns);
}

bool Mapper::poses_of_scan(TimestampNs first_ns, TimestampNs last_ns, localize::Pose3& first,
                           localize::Pose3& last) noexcept {
  TimestampNs horizon_ns = 0;
  // At the end of input a scan may reach a few milliseconds past the last pose: it takes the
  // last one for those beams rather than being lost.
  if (!poses_.horizon(horizon_ns) || !poses_.at(std::min(first_ns, horizon_ns), first) ||
      !poses_.at(std::min(last_ns, horizon_ns), last)) {
    return false;
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
  return true;
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
  // The planes of the tiles the window let go are final.
  registry_.finalize_outside(window_.bounds_m());
  give_detector_the_window();
  // Hough votes over overlapping sections, refitted and merged (PlaneDetector), less the
  // lasers' own scan planes.
  detector_.set_exclusions(scan_planes_.exclusions(config_.laser_count));
  const std::span<const msg::PlanePatch> planes = detector_.detect();
  count_detection(planes.size());
  if (path_on_) {
    path_.tie_walls_to_earlier_passes(planes, registry_, stamp_ns);
  }
  // Ids over time: each plane added, changed or joined to one it continues.
  registry_.update(planes, detector_.plane_moments(), stamp_ns);
  update_stamp_ns_ = stamp_ns;
  refit_buildings();
  if (path_on_ && path_.take_solved()) {
    view_due_ = config_.rigid_view;
  }
}

void Mapper::count_detection(std::size_t plane_count) noexcept {
  const planes::DetectionStats& stats = detector_.stats();
  counters_.peak_blocks = std::max(counters_.peak_blocks, detector_.voxels().block_count());
  counters_.peak_samples_without_room =
      std::max(counters_.peak_samples_without_room,
               window_.size() - std::min(window_.size(), detector_.voxels().size()));
  counters_.peak_section_planes =
      std::max(counters_.peak_section_planes, static_cast<std::size_t>(stats.section_planes));
  counters_.peak_detected_planes = std::max(counters_.peak_detected_planes, plane_count);
  counters_.scan_planes_rejected += stats.planes_excluded;
  counters_.sections_searched += stats.sections_searched;
  counters_.sections_replayed += stats.sections_replayed;
  counters_.sections_still_barren += stats.sections_still_barren;
  counters_.sections_settled += stats.sections_settled;
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
  if (poses_.horizon(horizon_ns) || scans_.size() == 0) {
    return;
  }
  // No pose yet, with the messages released so far applied. A scan that starts before the
  // oldest the first pose can be can never be drawn: it leaves the queue now, rather than when
  // the first pose comes. A filter waiting for its first fix would otherwise fill the queue,
  // and how full it got would depend on how the messages were batched between steps. The
  // extraction periods start from the first scan, as when it is drawn.
  TimestampNs first_pose_bound_ns = 0;
  if (!poses_.first_pose_bound(first_pose_bound_ns)) {
    return;
  }
  const TimestampNs oldest_ns = scans_.oldest_stamp();
  if (oldest_ns >= first_pose_bound_ns) {
    return;
  }
  if (!extraction_scheduled_) {
    extraction_scheduled_ = true;
    next_extraction_ns_ = oldest_ns + ns_from_seconds(config_.extract_every_s);
  }
  counters_.scans_without_pose += scans_.remove_before(first_pose_bound_ns);
}

bool Mapper::step() noexcept {
  registry_.begin_update();
  changes_ = {};
  // The rigid path's latest solve moves the planes, in an update of its own.
  if (show_planes_where_the_path_puts_them()) {
    return report_changes();
  }
  // Odometry, IMU and fixes (or given poses) to the pose source, in time order.
  reorder_.release_due(ending_, [this](const TimedMessage& message) { feed_poses(message); });
  drop_scans_before_first_pose();
  // Each scan with its poses into the voxel window; every extract_every_s of scans, the
  // window's planes detected and registered, and the buildings fitted to them.
  if (draw_scans_until_extraction()) {
    return report_changes();
  }
  // The end: a last extraction, then every plane final where the whole path puts it.
  if (ending_ && reorder_.size() == 0 && finish_map()) {
    return report_changes();
  }
  return false;
}

bool Mapper::report_changes() noexcept {
  changes_ = registry_.changes();
  return true;
}

bool Mapper::show_planes_where_the_path_puts_them() noexcept {
  if (view_due_ && final_extracted_) {
    view_due_ = false;  // the end's solve and move come next, and report every plane moved
  }
  if (!view_due_) {
    return false;
  }
  // As updates of their own at the last extraction's time, each within one datagram.
  view_due_ = !registry_.refresh_view(kChangesPerDatagram);
  if (registry_.changes().empty()) {
    return false;
  }
  refit_buildings();
  return true;
}

bool Mapper::draw_scans_until_extraction() noexcept {
  TimestampNs oldest_waiting_ns = 0;
  for (std::ptrdiff_t next = next_ready_scan(oldest_waiting_ns); next >= 0;
       next = next_ready_scan(oldest_waiting_ns)) {
    const auto position = static_cast<std::size_t>(next);
    const CompactScanHeader& queued = scans_.header(position);
    const TimestampNs stamp_ns = queued.header.stamp_ns;
    if (ending_ && reorder_.size() == 0) {
      poses_.localizer().flush_map_pose(queued.last_beam_ns);  // the last lag's scans
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
      return false;
    }
    if (stamp_ns >= next_extraction_ns_ && window_.placed()) {
      // Every scan before this one is in: the planes of the last period.
      extract(next_extraction_ns_);
      while (next_extraction_ns_ <= stamp_ns) {  // a gap in the scans is one extraction
        next_extraction_ns_ += ns_from_seconds(config_.extract_every_s);
      }
      return true;
    }
    draw_scan(position);
    scans_.remove(position);
  }
  return false;
}

bool Mapper::finish_map() noexcept {
  if (!final_extracted_) {
    final_extracted_ = true;
    if (window_.placed()) {
      extract(last_scan_ns_);
      return true;
    }
  }
  if (finalized_) {
    return join_final_planes();
  }
  finalized_ = true;
  if (path_on_) {
    path_.solve_final();
  }
  registry_.finalize_all();
  if (path_on_) {
    path_.move_finals(registry_);
  }
  update_stamp_ns_ = last_scan_ns_;
  refit_buildings();
  return true;
}

bool Mapper::join_final_planes() noexcept {
  if (!path_on_ || !config_.rigid_join_finals || finals_joined_) {
    return false;
  }
  finals_joined_ = registry_.join_finals_on_one_surface(kChangesPerDatagram);
  if (registry_.changes().empty()) {
    return false;
  }
  refit_buildings();
  return true;
}

}  // namespace blockmap::pipeline
